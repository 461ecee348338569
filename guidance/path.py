"""Straight-leg geometry in the horizontal NED plane [m]."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np


class LegProgress(NamedTuple):
    """Where a position is relative to a leg (immutable; a named tuple: made several times per
    control step and per log tick, a frozen dataclass costs several times more to build)."""

    along_m: float  # distance flown along the leg from its start [m]
    length_m: float  # horizontal leg length [m]
    cross_m: float  # signed cross-track distance, right of the leg positive [m]
    to_end_m: float  # horizontal distance to the leg's end [m]
    bearing_rad: float  # leg direction from north [rad]

    @property
    def fraction(self) -> float:
        return min(max(self.along_m / self.length_m, 0.0), 1.0) if self.length_m > 0 else 1.0


def leg_progress(pos: np.ndarray, a: np.ndarray, b: np.ndarray) -> LegProgress:
    """Where ``pos`` is relative to the leg a -> b (horizontal components only; NED [m], 3
    components each)."""
    an, ae, _ = a.tolist()
    bn, be, _ = b.tolist()
    qn, qe, _ = pos.tolist()
    dn, de = bn - an, be - ae
    pn, pe = qn - an, qe - ae
    length = math.hypot(dn, de)
    if length < 1e-9:
        return LegProgress(0.0, 0.0, 0.0, math.hypot(pn, pe), 0.0)
    un, ue = dn / length, de / length
    along = pn * un + pe * ue
    cross = -pn * ue + pe * un
    return LegProgress(along, length, cross, math.hypot(dn - pn, de - pe), math.atan2(de, dn))
