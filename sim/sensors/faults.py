"""Fault injection on a sensor's output vector, each switched on and off at given sim times.

Kinds: ``bias_step`` adds ``value`` (scalar or one number per axis, in the output unit);
``stuck`` freezes the output at the last value delivered before the fault; ``dropout`` delivers
nothing (for the GNSS this is the loss of fix). Faults are active on ``t_start <= t < t_end``.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import model_validator

from sim.sensors.config import SensorConfigError, StrictConfig


class SensorFault(StrictConfig):
    """One fault: kind, activation window [s] and, for ``bias_step``, the added value."""

    kind: Literal["bias_step", "stuck", "dropout"]
    t_start: float
    t_end: float = math.inf
    value: float | tuple[float, ...] | None = None

    model_config = StrictConfig.model_config | {"allow_inf_nan": True}

    @model_validator(mode="after")
    def _check(self):
        if not math.isfinite(self.t_start) or self.t_start < 0.0:
            raise ValueError(f"t_start must be finite and >= 0 (got {self.t_start})")
        if not self.t_end > self.t_start:
            raise ValueError(f"t_end ({self.t_end}) must be after t_start ({self.t_start})")
        if self.kind == "bias_step":
            vals = () if self.value is None else self.value if isinstance(self.value, tuple) else (self.value,)
            if not vals or not all(math.isfinite(v) for v in vals):
                raise ValueError("bias_step needs a finite value (scalar or one per axis)")
        elif self.value is not None:
            raise ValueError(f"{self.kind} takes no value")
        return self

    def active(self, t: float) -> bool:
        return self.t_start <= t < self.t_end


class SensorFaultSchedule:
    """The faults of one sensor with output dimension ``dim`` (``None``: any length)."""

    def __init__(self, sensor: str, dim: int | None):
        self.sensor = sensor
        self.dim = dim
        self.faults: list[SensorFault] = []
        self._offsets: list[np.ndarray | float] = []
        self._frozen: dict[int, np.ndarray] = {}
        self._last: np.ndarray | None = None

    def add(self, fault: SensorFault) -> None:
        if (
            fault.kind == "bias_step"
            and isinstance(fault.value, tuple)
            and (self.dim is None or len(fault.value) != self.dim)
        ):
            raise SensorConfigError(
                f"{self.sensor}: bias_step value has {len(fault.value)} axes, output has {self.dim}"
            )
        self.faults.append(fault)
        self._offsets.append(np.asarray(fault.value, float) if fault.kind == "bias_step" else 0.0)

    def active(self, t: float) -> list[SensorFault]:
        return [f for f in self.faults if f.active(t)]

    def apply(self, t: float, y: np.ndarray) -> np.ndarray | None:
        """Faulted output at time ``t`` [s], or ``None`` when it is dropped."""
        for i, f in enumerate(self.faults):
            if not f.active(t):
                self._frozen.pop(i, None)
                continue
            if f.kind == "dropout":
                return None
            if f.kind == "stuck":
                if i not in self._frozen:
                    self._frozen[i] = (self._last if self._last is not None else y).copy()
                y = self._frozen[i]
            else:
                y = y + self._offsets[i]
        self._last = y
        return y
