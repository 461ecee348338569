"""Measurements as the sensors deliver them. ``t`` is the time of validity (sample time) [s];
a measurement reaches the estimator ``latency_s`` later. Frames and units per field."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, slots=True)
class ImuSample:
    """Specific force [m/s^2] and angular rate [rad/s], both body FRD."""

    t: float
    accel_body: np.ndarray
    gyro_body: np.ndarray


@dataclass(frozen=True, slots=True)
class GnssFix:
    """Antenna position local NED [m] and velocity NED [m/s] (receiver output in our frame)."""

    t: float
    pos_ned: np.ndarray
    vel_ned: np.ndarray


@dataclass(frozen=True, slots=True)
class BaroSample:
    """Static pressure [Pa]."""

    t: float
    pressure_pa: float


@dataclass(frozen=True, slots=True)
class AirspeedSample:
    """Pitot-static differential (dynamic) pressure [Pa]."""

    t: float
    diff_pressure_pa: float


@dataclass(frozen=True, slots=True)
class MagSample:
    """Magnetic flux density, body FRD [uT]."""

    t: float
    field_body_ut: np.ndarray


@dataclass(frozen=True, slots=True)
class AdsbReport:
    """Position NED [m] and velocity NED [m/s] of aircraft ``id`` broadcast at time ``t``."""

    t: float
    id: str
    pos_ned: np.ndarray
    vel_ned: np.ndarray
    cooperative: bool = False


Measurement = ImuSample | GnssFix | BaroSample | AirspeedSample | MagSample
