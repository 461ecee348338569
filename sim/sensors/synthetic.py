"""Kinematic truth for testing and tuning estimators without JSBSim: smooth flights made of
segments (straight, coordinated turn, climb, hover) sampled as :class:`TruthSample`.

A segment holds a horizontal ground speed [m/s], a turn rate [rad/s] and a climb rate [m/s];
each blends from the previous segment's values with a C2 smoothstep of ``ramp_s``, so the
acceleration and body rates are continuous. Attitude: a ``fixed_wing`` flies coordinated (no
lateral specific force) with its x axis on the air-relative velocity pitched up by ``alpha_rad``;
a ``multirotor`` points its thrust axis (-z) along the specific force and its nose along the
track heading. Body rates come from the attitude by central differences, the specific force is
``R^T (a - g)``. Air data: ISA at the geometric altitude ``origin.alt_m - D``, constant wind.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from sim.core.constants import STANDARD_GRAVITY
from sim.core.state import VehicleState
from sim.geodesy import GeoPoint, ned_to_geodetic
from sim.sensors import isa
from sim.sensors.truth import TruthSample


@dataclass(frozen=True, slots=True)
class Segment:
    duration_s: float
    speed_mps: float
    turn_rate_rps: float = 0.0
    climb_rate_mps: float = 0.0
    ramp_s: float = 3.0


def _profile(t: np.ndarray, segments: Sequence[Segment], attr: str) -> tuple[np.ndarray, np.ndarray]:
    """Value and time derivative of one segment attribute along ``t``."""
    val = np.zeros_like(t)
    der = np.zeros_like(t)
    prev, t0 = getattr(segments[0], attr), 0.0
    for seg in segments:
        target = getattr(seg, attr)
        m = t >= t0
        x = np.clip((t[m] - t0) / seg.ramp_s, 0.0, 1.0)
        s = x**3 * (10 - 15 * x + 6 * x * x)
        ds = 30 * x * x * (1 - x) ** 2 / seg.ramp_s
        val[m] = prev + (target - prev) * s
        der[m] = (target - prev) * ds
        prev, t0 = target, t0 + seg.duration_s
    return val, der


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


@dataclass(frozen=True)
class SyntheticFlight:
    """Arrays over the sample times ``t`` (K,): NED pos/vel [m, m/s], Euler [rad], body rates
    [rad/s], specific force body [m/s^2], TAS [m/s], static pressure [Pa], temperature [K],
    density [kg/m^3]."""

    t: np.ndarray
    pos_ned: np.ndarray
    vel_ned: np.ndarray
    euler: np.ndarray
    rates_body: np.ndarray
    specific_force_body: np.ndarray
    tas: np.ndarray
    pressure: np.ndarray
    temperature: np.ndarray
    density: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    origin: GeoPoint
    wind_ned: np.ndarray

    def __len__(self) -> int:
        return len(self.t)

    def state(self, k: int) -> VehicleState:
        return VehicleState(
            t=float(self.t[k]),
            pos_ned=self.pos_ned[k],
            vel_ned=self.vel_ned[k],
            euler=self.euler[k],
            rates_body=self.rates_body[k],
            alt_msl_m=self.origin.alt_m - float(self.pos_ned[k, 2]),
            lat_deg=float(self.lat_deg[k]),
            lon_deg=float(self.lon_deg[k]),
            tas_mps=float(self.tas[k]),
            eas_mps=float(self.tas[k] * np.sqrt(self.density[k] / isa.RHO0)),
        )

    def sample(self, k: int) -> TruthSample:
        return TruthSample(
            self.state(k),
            self.specific_force_body[k],
            float(self.pressure[k]),
            float(self.temperature[k]),
            float(self.density[k]),
            self.wind_ned,
        )

    def samples(self) -> Iterator[TruthSample]:
        return (self.sample(k) for k in range(len(self.t)))


def generate(
    segments: Sequence[Segment],
    vehicle: Literal["fixed_wing", "multirotor"],
    rate_hz: float,
    origin: GeoPoint,
    start_ned=(0.0, 0.0, 0.0),
    heading_rad: float = 0.0,
    wind_ned=(0.0, 0.0, 0.0),
    alpha_rad: float = 0.05,
    g: float = STANDARD_GRAVITY,
) -> SyntheticFlight:
    """Sample the flight at ``rate_hz`` from t = 0 to the end of the last segment."""
    total = sum(s.duration_s for s in segments)
    h = 1.0 / rate_hz
    t = np.arange(round(total * rate_hz) + 1) * h
    vh, vh_dot = _profile(t, segments, "speed_mps")
    om, _ = _profile(t, segments, "turn_rate_rps")
    hd, hdd = _profile(t, segments, "climb_rate_mps")
    psi = heading_rad + np.concatenate(([0.0], np.cumsum(0.5 * (om[1:] + om[:-1]) * h)))
    c, s = np.cos(psi), np.sin(psi)
    vel = np.stack([vh * c, vh * s, -hd], axis=1)
    acc = np.stack([vh_dot * c - vh * om * s, vh_dot * s + vh * om * c, -hdd], axis=1)
    pos = np.asarray(start_ned, float) + np.concatenate(
        (np.zeros((1, 3)), np.cumsum(0.5 * (vel[1:] + vel[:-1]) * h, axis=0))
    )
    wind = np.asarray(wind_ned, float)
    f_ned = acc - np.array([0.0, 0.0, g])
    if vehicle == "fixed_wing":
        x = _unit(vel - wind)
        y = _unit(np.cross(x, f_ned))
        z = np.cross(x, y)
        ca, sa = np.cos(alpha_rad), np.sin(alpha_rad)
        x, z = ca * x - sa * z, sa * x + ca * z
    else:
        z = _unit(-f_ned)
        y = _unit(np.cross(z, np.stack([c, s, np.zeros_like(c)], axis=1)))
        x = np.cross(y, z)
    rot = np.stack([x, y, z], axis=2)  # columns: body axes in NED
    rdot = np.gradient(rot, h, axis=0)
    skew = np.einsum("kji,kjl->kil", rot, rdot)
    rates = 0.5 * np.stack(
        [skew[:, 2, 1] - skew[:, 1, 2], skew[:, 0, 2] - skew[:, 2, 0], skew[:, 1, 0] - skew[:, 0, 1]], axis=1
    )
    euler = np.stack(
        [
            np.arctan2(rot[:, 2, 1], rot[:, 2, 2]),
            -np.arcsin(np.clip(rot[:, 2, 0], -1, 1)),
            np.arctan2(rot[:, 1, 0], rot[:, 0, 0]),
        ],
        axis=1,
    )
    f_body = np.einsum("kji,kj->ki", rot, f_ned)
    alt = origin.alt_m - pos[:, 2]
    pressure = np.array([isa.pressure_at_altitude(a) for a in alt])
    temperature = np.array([isa.temperature_of_pressure(p) for p in pressure])
    lat, lon, _ = ned_to_geodetic(pos, origin)
    return SyntheticFlight(
        t,
        pos,
        vel,
        euler,
        rates,
        f_body,
        np.linalg.norm(vel - wind, axis=1),
        pressure,
        temperature,
        pressure / (isa.R_AIR * temperature),
        lat,
        lon,
        origin,
        wind,
    )
