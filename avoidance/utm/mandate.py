"""UTM mandates (spec §7.1, seed 000 §6.8.8 "Resolution/Mandate Enforcement"): orders of the
authority that are never broken, unlike resolutions (the collision cases of a directive, which a
UAS may break for an emerging threat: hand the peer to its emergency avoidance).

The seed gives one example and no format: a passenger aircraft in distress needs the airspace to
land safely, and the UAS must obey "even at event of own destruction". A mandate here is that
order: keep clear of a vertical cylinder (centre, radius, altitude band) from ``start`` until
``end`` (None: to the end of the run). The UAS applies it as a keep-out geofence in every
reach-set run, navigation and emergency alike (a hard constraint; the planner's relaxed runs,
which drop hard constraints when no path is left, can still drop it), and keeps obeying a
mandate it has received when its link is lost, until the mandate's end.
Frames: GCF (ENU) [m] for the centre; heights above the scenario origin [m]; sim seconds [s].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely

from sim.core.threats import Geofence


@dataclass(frozen=True, slots=True)
class Mandate:
    """Keep clear of the cylinder of ``radius`` [m] around ``centre`` (GCF east, north [m])
    between the heights ``up_min``..``up_max`` [m] from ``start`` to ``end`` [s]."""

    id: str
    start: float
    end: float | None
    centre: np.ndarray
    radius: float
    up_min: float = -math.inf
    up_max: float = math.inf

    def active(self, t: float) -> bool:
        """Whether the mandate binds at ``t`` [s]."""
        return self.start <= t and (self.end is None or t < self.end)

    def geofence(self) -> Geofence:
        """The keep-out geofence the UAS flies around (area in (north, east) [m])."""
        east, north = (float(x) for x in self.centre[:2])
        return Geofence(
            f"mandate:{self.id}", shapely.Point(north, east).buffer(self.radius, 16), self.up_min, self.up_max, False
        )

    def inside(self, pos_enu: np.ndarray) -> bool:
        """Whether a GCF position [m] is inside the cylinder."""
        horizontal = float(np.hypot(*(np.asarray(pos_enu, float)[:2] - self.centre[:2])))
        return horizontal < self.radius and self.up_min <= float(pos_enu[2]) <= self.up_max

    def record(self) -> dict:
        """JSON-ready values (unbounded heights and end as null)."""
        return {
            "id": self.id,
            "kind": "keep_clear",
            "start_t": self.start,
            "end_t": self.end,
            "centre_enu": [float(x) for x in self.centre[:2]],
            "radius_m": self.radius,
            "up_min_m": None if math.isinf(self.up_min) else self.up_min,
            "up_max_m": None if math.isinf(self.up_max) else self.up_max,
        }

    @classmethod
    def from_record(cls, r: dict) -> Mandate:
        """The mandate of a :meth:`record` (a logged directive's)."""
        return cls(
            r["id"],
            r["start_t"],
            r["end_t"],
            np.asarray(r["centre_enu"], float),
            r["radius_m"],
            -math.inf if r["up_min_m"] is None else r["up_min_m"],
            math.inf if r["up_max_m"] is None else r["up_max_m"],
        )
