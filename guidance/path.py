"""Straight-leg geometry in the horizontal NED plane [m]."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, slots=True)
class LegProgress:
    along_m: float  # distance flown along the leg from its start [m]
    length_m: float  # horizontal leg length [m]
    cross_m: float  # signed cross-track distance, right of the leg positive [m]
    to_end_m: float  # horizontal distance to the leg's end [m]
    bearing_rad: float  # leg direction from north [rad]

    @property
    def fraction(self) -> float:
        return min(max(self.along_m / self.length_m, 0.0), 1.0) if self.length_m > 0 else 1.0


def leg_progress(pos: np.ndarray, a: np.ndarray, b: np.ndarray) -> LegProgress:
    """Where ``pos`` is relative to the leg a -> b (horizontal components only)."""
    dn, de = float(b[0] - a[0]), float(b[1] - a[1])
    pn, pe = float(pos[0] - a[0]), float(pos[1] - a[1])
    length = math.hypot(dn, de)
    if length < 1e-9:
        return LegProgress(0.0, 0.0, 0.0, math.hypot(pn, pe), 0.0)
    un, ue = dn / length, de / length
    along = pn * un + pe * ue
    cross = -pn * ue + pe * un
    return LegProgress(along, length, cross, math.hypot(dn - pn, de - pe), math.atan2(de, dn))
