"""What every sampled sensor shares: output rate, latency (delay line) and fault injection.

The world calls :meth:`SampledSensor.poll` once per tick with the truth of that tick. The
sensor samples when a sample is due (times ``k / rate_hz``; one sample per call, so the world
must poll at least at the sensor rate), applies its error model and faults, and returns the
measurements whose latency has elapsed, oldest first.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Generic, TypeVar

import numpy as np
from pydantic import Field

from sim.sensors.config import StrictConfig
from sim.sensors.faults import SensorFault, SensorFaultSchedule
from sim.sensors.truth import TruthSample

M = TypeVar("M")
_EPS = 1e-9


class SensorConfig(StrictConfig):
    """Output rate [Hz], latency (time of validity to delivery) [s] and ``dropout``, the
    probability that a sample is lost (drawn per sample from the sensor's own generator)."""

    rate_hz: float = Field(gt=0.0)
    latency_s: float = Field(0.0, ge=0.0)
    dropout: float = Field(0.0, ge=0.0, lt=1.0)


class SampledSensor(Generic[M]):
    """Base class: subclasses implement ``_measure`` (truth -> erroneous vector, advancing their
    error states by ``dt`` [s]) and ``_package`` (time, vector -> measurement)."""

    name = "sensor"
    dim: int | None = None

    def __init__(self, cfg: SensorConfig, rng: np.random.Generator):
        self.cfg = cfg
        self.rng = rng
        self.faults = SensorFaultSchedule(self.name, self.dim)
        self._period = 1.0 / cfg.rate_hz
        self._next_k = 0
        self._last_t: float | None = None
        self._pending: deque[tuple[float, float, np.ndarray]] = deque()

    def inject(self, fault: SensorFault) -> None:
        """Schedule a fault (may be called at any time; effective from ``fault.t_start``)."""
        self.faults.add(fault)

    def next_sample_t(self) -> float:
        """Time [s] the next sample is due."""
        return self._next_k * self._period

    def next_delivery_t(self) -> float:
        """Time [s] the oldest pending measurement is delivered (inf: none pending)."""
        return self._pending[0][0] if self._pending else math.inf

    def poll(self, truth: TruthSample) -> list[M]:
        """Sample ``truth`` if a sample is due at its time, then :meth:`deliver`."""
        t = truth.t
        if t + _EPS >= self.next_sample_t():
            dt = self._period if self._last_t is None else t - self._last_t
            self._last_t = t
            self._next_k = math.floor((t + _EPS) / self._period) + 1
            y = self.faults.apply(t, self._measure(truth, dt))
            lost = self.cfg.dropout > 0.0 and self.rng.random() < self.cfg.dropout
            if y is not None and not lost:
                self._pending.append((t + self.cfg.latency_s, t, y))
        return self.deliver(t)

    def deliver(self, t: float) -> list[M]:
        """The measurements whose latency has elapsed at ``t`` [s], oldest first."""
        out: list[M] = []
        pending = self._pending
        while pending and pending[0][0] <= t + _EPS:
            _, ts, y = pending.popleft()
            out.append(self._package(ts, y))
        return out

    def _measure(self, truth: TruthSample, dt: float) -> np.ndarray:
        raise NotImplementedError

    def _package(self, t: float, y: np.ndarray) -> M:
        raise NotImplementedError
