"""Frame conversions, in one place.

- WGS84 geodetic (lat, lon [deg], h [m] above the ellipsoid) <-> local NED [m] around an origin,
  through ECEF (pymap3d), exact at any distance from the origin.
- JSBSim speaks feet and knots; SI conversions live here too.
- The seed algorithms are z-up (ENU); ``ned_to_enu`` / ``enu_to_ned`` are the one boundary.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pymap3d

FT = 0.3048  # m per ft
KT = 1852.0 / 3600.0  # m/s per knot
SLUG_FT2 = 1.3558179483314004  # kg m^2 per slug ft^2


@dataclass(frozen=True, slots=True)
class GeoPoint:
    """A WGS84 point: latitude and longitude [deg], height above the ellipsoid [m]."""

    lat_deg: float
    lon_deg: float
    alt_m: float = 0.0


def geodetic_to_ned(lat_deg, lon_deg, alt_m, origin: GeoPoint) -> np.ndarray:
    """Local NED [m] of geodetic point(s) relative to ``origin``; arrays broadcast, last axis NED."""
    n, e, d = pymap3d.geodetic2ned(lat_deg, lon_deg, alt_m, origin.lat_deg, origin.lon_deg, origin.alt_m)
    return np.stack([np.asarray(n, float), np.asarray(e, float), np.asarray(d, float)], axis=-1)


def ned_to_geodetic(ned, origin: GeoPoint) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Geodetic (lat [deg], lon [deg], alt [m]) of local NED point(s) relative to ``origin``."""
    ned = np.asarray(ned, float)
    lat, lon, alt = pymap3d.ned2geodetic(ned[..., 0], ned[..., 1], ned[..., 2],
                                         origin.lat_deg, origin.lon_deg, origin.alt_m)
    return np.asarray(lat, float), np.asarray(lon, float), np.asarray(alt, float)


def ned_to_enu(v) -> np.ndarray:
    """NED vector(s) to ENU (z-up), last axis."""
    v = np.asarray(v, float)
    return np.stack([v[..., 1], v[..., 0], -v[..., 2]], axis=-1)


def enu_to_ned(v) -> np.ndarray:
    """ENU vector(s) to NED, last axis (the map is its own inverse)."""
    return ned_to_enu(v)


def wrap_pi(a):
    """Angle(s) wrapped to (-pi, pi] [rad]."""
    return np.pi - np.mod(np.pi - np.asarray(a, float), 2.0 * np.pi)


def euler_to_quaternion(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    """Quaternion (x, y, z, w) of the 3-2-1 rotation body FRD -> NED [rad in]."""
    cr, sr = np.cos(roll / 2), np.sin(roll / 2)
    cp, sp = np.cos(pitch / 2), np.sin(pitch / 2)
    cy, sy = np.cos(yaw / 2), np.sin(yaw / 2)
    return (
        float(sr * cp * cy - cr * sp * sy),
        float(cr * sp * cy + sr * cp * sy),
        float(cr * cp * sy - sr * sp * cy),
        float(cr * cp * cy + sr * sp * sy),
    )
