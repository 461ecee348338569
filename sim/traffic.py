"""Scripted traffic objects: spheres at constant velocity (not flown by JSBSim).

Position at sim time ``t`` [s]: ``p0 + v (t - appear)`` in the local-level NED frame [m]; an
object exists from its ``appear`` time on.
"""

from __future__ import annotations

import numpy as np

from sim import scenario as sc
from sim.core.state import VehicleState
from sim.estimation.geodetic import LocalGeodetic
from sim.geodesy import GeoPoint


class TrafficObject:
    def __init__(self, cfg: sc.TrafficObject, origin: GeoPoint):
        self.id = cfg.id
        self.radius_m = cfg.radius
        self.cooperative = cfg.cooperative
        self.appear = cfg.appear
        self.p0 = np.array([cfg.north, cfg.east, origin.alt_m - cfg.altitude])
        self.v = np.array([cfg.velocity.north, cfg.velocity.east, cfg.velocity.down])
        self._geo = LocalGeodetic(origin)

    def exists(self, t: float) -> bool:
        return t >= self.appear

    def position(self, t) -> np.ndarray:
        """NED [m] at time(s) ``t`` (array input gives (N, 3))."""
        dt = np.asarray(t, float) - self.appear
        return self.p0 + dt[..., None] * self.v if dt.ndim else self.p0 + float(dt) * self.v

    def state(self, t: float) -> VehicleState:
        """The object's true state, as sensors see it (heading along its velocity)."""
        p = self.position(t)
        lat, lon, alt = self._geo.ned_to_geodetic(*p.tolist())
        yaw = float(np.arctan2(self.v[1], self.v[0])) if np.any(self.v[:2]) else 0.0
        return VehicleState(
            t=t,
            pos_ned=p,
            vel_ned=self.v.copy(),
            euler=np.array([0.0, 0.0, yaw]),
            rates_body=np.zeros(3),
            alt_msl_m=float(alt),
            lat_deg=float(lat),
            lon_deg=float(lon),
            tas_mps=float(np.linalg.norm(self.v)),
        )
