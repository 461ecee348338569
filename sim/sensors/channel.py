"""Error model of one measured vector: scale factor, bias (turn-on + random walk), white noise,
quantisation — applied per axis, in the unit of the measured quantity.

``y = q(s * x + b + n)`` with ``s = 1 + N(0, scale_factor_std^2)`` drawn once, ``b`` drawn
``N(0, bias_init_std^2)`` at start and integrating white noise of density ``bias_rw``
[unit/sqrt(s)] between samples, ``n ~ N(0, noise_std^2)`` per sample and ``q`` rounding to
multiples of ``quantum`` (none when 0).
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from sim.sensors.config import StrictConfig


class ChannelConfig(StrictConfig):
    """Per-axis error parameters [unit of the quantity; bias_rw in unit/sqrt(s)]."""

    noise_std: float = Field(0.0, ge=0.0)
    bias_init_std: float = Field(0.0, ge=0.0)
    bias_rw: float = Field(0.0, ge=0.0)
    scale_factor_std: float = Field(0.0, ge=0.0, lt=0.5)
    quantum: float = Field(0.0, ge=0.0)


class Channel:
    """State of one channel's errors (``dim`` axes) drawing from ``rng``."""

    __slots__ = ("_rng", "bias", "cfg", "dim", "scale")

    def __init__(self, cfg: ChannelConfig, dim: int, rng: np.random.Generator):
        self.cfg = cfg
        self.dim = dim
        self._rng = rng
        self.scale = 1.0 + cfg.scale_factor_std * rng.standard_normal(dim)
        self.bias = cfg.bias_init_std * rng.standard_normal(dim)

    def apply(self, true: np.ndarray, dt: float) -> np.ndarray:
        """Measured value of ``true`` after ``dt`` [s] since the previous sample. Plain float
        arithmetic per axis (a sensor sample has 1 to 3 axes), the same operations in the same
        order as :meth:`apply_block`'s arrays: the same bits, the sign of a zero included."""
        c = self.cfg
        if c.bias_rw > 0.0 and dt > 0.0:
            self.bias += (c.bias_rw * math.sqrt(dt)) * self._rng.standard_normal(self.dim)
        y = [s * x + b for s, x, b in zip(self.scale.tolist(), true.tolist(), self.bias.tolist(), strict=True)]
        if c.noise_std > 0.0:
            k = c.noise_std
            y = [v + k * e for v, e in zip(y, self._rng.standard_normal(self.dim).tolist(), strict=True)]
        if c.quantum > 0.0:
            q = c.quantum
            y = [math.copysign(q * round(v / q), v) for v in y]  # round half to even, as numpy's
        return np.array(y)

    def apply_block(self, true: np.ndarray, dt: float) -> np.ndarray:
        """Measured values of ``true`` (n, dim), sampled every ``dt`` [s] after the previous
        sample; the same model as :meth:`apply` row by row (bias random walk per sample), drawn
        in one go (bias steps of all rows first, then the white noise of all rows)."""
        c = self.cfg
        n = true.shape[0]
        if c.bias_rw > 0.0 and dt > 0.0:
            b = np.cumsum((c.bias_rw * math.sqrt(dt)) * self._rng.standard_normal((n, self.dim)), axis=0)
            b += self.bias
            self.bias = b[-1].copy()
        else:
            b = self.bias
        y = self.scale * true + b
        if c.noise_std > 0.0:
            y += c.noise_std * self._rng.standard_normal((n, self.dim))
        if c.quantum > 0.0:
            y = c.quantum * np.round(y / c.quantum)
        return y
