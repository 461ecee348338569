"""Where a ground station may send a vehicle: the check of every mission item and position target.

A point is in the envelope when it is finite, at or above the ground (the scenario's flat ground
at the origin altitude) and at most ``max_height_m`` above it, within ``max_range_m``
horizontally of the origin, inside every keep-in geofence's area and altitude band and outside
every keep-out geofence's. Points are in the scenario's local-level NED frame [m] (up = -D,
heights relative to the origin = the ground).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pymavlink.dialects.v20 import common as mav
from shapely import contains_xy

from sim.core.threats import Geofence

# (max height above the ground [m], max range from the origin [m]) when the scenario sets none
DEFAULT_LIMITS = {"fixed_wing": (25_000.0, 500_000.0), "multirotor": (1_000.0, 20_000.0)}


@dataclass(frozen=True, slots=True)
class Refusal:
    """Why a point is refused: ``result`` the MAV_MISSION_RESULT a mission item gets
    (INVALID_PARAM5_X for horizontal position, INVALID_PARAM7 for altitude, DENIED for a
    geofence), ``reason`` one line for the log."""

    result: int
    reason: str


@dataclass(frozen=True, slots=True)
class Envelope:
    max_height_m: float
    max_range_m: float
    fences: tuple[Geofence, ...] = ()

    def check(self, ned: np.ndarray) -> Refusal | None:
        """``None`` if the NED point [m] is in the envelope, else why not."""
        n, e, d = (float(x) for x in ned)
        if not (math.isfinite(n) and math.isfinite(e)):
            return Refusal(mav.MAV_MISSION_INVALID_PARAM5_X, "position not finite")
        if not math.isfinite(d):
            return Refusal(mav.MAV_MISSION_INVALID_PARAM7, "altitude not finite")
        up, r = -d, math.hypot(n, e)
        if up < 0.0:
            return Refusal(mav.MAV_MISSION_INVALID_PARAM7, f"{-up:.4g} m below the ground")
        if up > self.max_height_m:
            return Refusal(
                mav.MAV_MISSION_INVALID_PARAM7, f"{up:.4g} m above the ground (at most {self.max_height_m:g} m)"
            )
        if r > self.max_range_m:
            return Refusal(
                mav.MAV_MISSION_INVALID_PARAM5_X, f"{r:.4g} m from the origin (at most {self.max_range_m:g} m)"
            )
        for f in self.fences:
            inside = bool(contains_xy(f.area, n, e)) and f.up_min_m <= up <= f.up_max_m
            if inside != f.keep_in:
                where = "outside keep-in" if f.keep_in else "inside keep-out"
                return Refusal(mav.MAV_MISSION_DENIED, f"{where} geofence {f.id!r}")
        return None
