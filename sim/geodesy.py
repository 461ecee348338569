"""The scenario frame's geodetic mapping (engine side; the frame itself is ``sim.core.frames``).

- WGS84 geodetic (lat, lon [deg], h [m] above the ellipsoid, which JSBSim calls sea level) <->
  the scenario's *local-level NED* frame [m]: north and east are the tangent-plane projection at
  the origin (through ECEF, pymap3d), down is ``origin.alt - h``. A level flight thus has constant
  D at any range (a pure tangent plane would put it 31 m "higher" after 20 km).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pymap3d


@dataclass(frozen=True, slots=True)
class GeoPoint:
    """A WGS84 point: latitude and longitude [deg], height above the ellipsoid [m]."""

    lat_deg: float
    lon_deg: float
    alt_m: float = 0.0


_R_MEAN = 6_371_008.8  # mean earth radius [m], only for the curvature drop of the inverse
_WGS84_A = 6_378_137.0  # semi-major axis [m]
_WGS84_E2 = 6.69437999014e-3  # first eccentricity squared


def _ecef(lat_rad: float, lon_rad: float, h: float) -> tuple[float, float, float]:
    sl, cl = math.sin(lat_rad), math.cos(lat_rad)
    n = _WGS84_A / math.sqrt(1.0 - _WGS84_E2 * sl * sl)
    return ((n + h) * cl * math.cos(lon_rad), (n + h) * cl * math.sin(lon_rad), (n * (1.0 - _WGS84_E2) + h) * sl)


class LocalLevelFrame:
    """The scenario frame around one origin, for one point at a time in the simulation loop:
    the same mapping as :func:`geodetic_to_ned` (which serves arrays), in plain float math with
    the origin's ECEF position and rotation cached (~1 us instead of ~90 us a call)."""

    def __init__(self, origin: GeoPoint):
        self.origin = origin
        lat, lon = math.radians(origin.lat_deg), math.radians(origin.lon_deg)
        self._x0, self._y0, self._z0 = _ecef(lat, lon, origin.alt_m)
        sl, cl, so, co = math.sin(lat), math.cos(lat), math.sin(lon), math.cos(lon)
        self._north = (-sl * co, -sl * so, cl)
        self._east = (-so, co, 0.0)

    def ned(self, lat_deg: float, lon_deg: float, alt_m: float) -> tuple[float, float, float]:
        """Local-level NED [m] of one geodetic point."""
        x, y, z = _ecef(math.radians(lat_deg), math.radians(lon_deg), alt_m)
        dx, dy, dz = x - self._x0, y - self._y0, z - self._z0
        nx, ny, nz = self._north
        ex, ey, _ = self._east
        return nx * dx + ny * dy + nz * dz, ex * dx + ey * dy, self.origin.alt_m - alt_m


def geodetic_to_ned(lat_deg, lon_deg, alt_m, origin: GeoPoint) -> np.ndarray:
    """Local-level NED [m] of geodetic point(s) relative to ``origin``; last axis N, E, D."""
    n, e, _ = pymap3d.geodetic2ned(lat_deg, lon_deg, alt_m, origin.lat_deg, origin.lon_deg, origin.alt_m)
    d = origin.alt_m - np.asarray(alt_m, float)
    return np.stack(np.broadcast_arrays(np.asarray(n, float), np.asarray(e, float), d), axis=-1)


def ned_to_geodetic(ned, origin: GeoPoint) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Geodetic (lat [deg], lon [deg], alt [m]) of local-level NED point(s) (inverse of
    :func:`geodetic_to_ned`; the tangent-plane D is corrected by the curvature drop, exact to
    millimetres within 100 km)."""
    ned = np.asarray(ned, float)
    n, e, d = ned[..., 0], ned[..., 1], ned[..., 2]
    d_tangent = d + (n * n + e * e) / (2.0 * _R_MEAN)
    lat, lon, _ = pymap3d.ned2geodetic(n, e, d_tangent, origin.lat_deg, origin.lon_deg, origin.alt_m)
    return np.asarray(lat, float), np.asarray(lon, float), origin.alt_m - d
