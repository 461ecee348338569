"""Vehicle state as seen by controllers, guidance and planners.

Frames and units (SI throughout):
- position: local NED [m] relative to the scenario origin (a WGS84 point on the ellipsoid
  surface); ``alt_msl_m`` is the geometric altitude above mean sea level [m].
- velocity: NED [m/s] relative to the ground.
- attitude: roll, pitch, yaw (3-2-1 Euler, body FRD to NED) [rad], yaw in (-pi, pi].
- body rates p, q, r about body FRD axes [rad/s].
- airspeeds: true (TAS) and equivalent (EAS) [m/s].

``AttitudeSample`` is what an airframe's inner attitude/rate loops see at one gyro sample.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np


@dataclass(slots=True)
class VehicleState:
    """Kinematic and air-data state of one vehicle at sim time ``t`` [s]. ``pos_sigma_m``: the
    estimate's 1-sigma position uncertainty along N, E, D [m] (the estimator's covariance
    diagonal); None where nothing is estimated (truth, perfect sensors)."""

    t: float
    pos_ned: np.ndarray
    vel_ned: np.ndarray
    euler: np.ndarray
    rates_body: np.ndarray
    alt_msl_m: float
    lat_deg: float
    lon_deg: float
    tas_mps: float = 0.0
    eas_mps: float = 0.0
    alpha_rad: float = 0.0
    beta_rad: float = 0.0
    extra: dict[str, float] = field(default_factory=dict)
    pos_sigma_m: np.ndarray | None = None

    @property
    def roll(self) -> float:
        return float(self.euler[0])

    @property
    def pitch(self) -> float:
        return float(self.euler[1])

    @property
    def yaw(self) -> float:
        return float(self.euler[2])

    @property
    def ground_speed_mps(self) -> float:
        return float(np.hypot(self.vel_ned[0], self.vel_ned[1]))

    @property
    def course_rad(self) -> float:
        """Ground track angle from north, positive east [rad]."""
        return float(np.arctan2(self.vel_ned[1], self.vel_ned[0]))


class AttitudeSample(NamedTuple):
    """Inner-loop inputs at sim time ``t`` [s]: attitude ``euler`` (roll, pitch, yaw; 3-2-1 Euler,
    body FRD to NED) [rad] and body rates ``rates_body`` (p, q, r about body FRD) [rad/s].
    Immutable; a named tuple because one is made at every gyro sample."""

    t: float
    euler: tuple[float, float, float]
    rates_body: tuple[float, float, float]
