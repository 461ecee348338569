"""Setpoints handed from guidance to the flight controllers.

Frames and units: NED [m, m/s], angles [rad], altitude above MSL [m], airspeed true (TAS) [m/s].
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(slots=True)
class FixedWingSetpoint:
    """Fixed-wing outer-loop demand: bank angle, altitude MSL and true airspeed."""

    roll_rad: float
    altitude_m: float
    tas_mps: float


@dataclass(slots=True)
class MultirotorSetpoint:
    """Multirotor demand: NED position, feed-forward NED velocity and yaw."""

    pos_ned: np.ndarray
    vel_ned: np.ndarray = field(default_factory=lambda: np.zeros(3))
    yaw_rad: float = 0.0
