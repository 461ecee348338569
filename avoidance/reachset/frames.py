"""Frames of the reach-set avoidance, and the one boundary to the project's NED frame.

- Project frame: local-level NED from the scenario origin [m]; yaw from north, positive east [rad].
- GCF (global, z-up, spec §0.1): ENU [m] from the same origin (``sim.core.frames.ned_to_enu``); heading
  ``psi`` from east, positive counter-clockwise (towards north) [rad]: ``psi = pi/2 - yaw_ned``.
- LCF (local grid frame): origin at the grid's pose, X+ = heading (level, yaw only, A-12),
  Y+ = left, Z+ = up [m]. Polar: ``d = |p|``, ``theta = atan2(y, x)`` (left positive),
  ``phi = atan2(z, hypot(x, y))`` (up positive) [m, rad].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.core.frames import enu_to_ned, ned_to_enu, wrap_pi


def heading_from_yaw_ned(yaw_ned: float) -> float:
    """GCF heading [rad] of a NED yaw [rad]."""
    return float(wrap_pi(np.pi / 2 - yaw_ned))


def to_polar(p: np.ndarray) -> np.ndarray:
    """Cartesian LCF points (..., 3) to polar (d, theta, phi) (..., 3) [m, rad, rad]."""
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    rho = np.hypot(x, y)
    return np.stack([np.hypot(rho, z), np.arctan2(y, x), np.arctan2(z, rho)], axis=-1)


def from_polar(dtp: np.ndarray) -> np.ndarray:
    """Polar (d, theta, phi) (..., 3) to Cartesian LCF points (..., 3)."""
    d, th, ph = dtp[..., 0], dtp[..., 1], dtp[..., 2]
    c = d * np.cos(ph)
    return np.stack([c * np.cos(th), c * np.sin(th), d * np.sin(ph)], axis=-1)


def rotation_zyx(att: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of z-up attitudes (..., 3) = (roll, pitch, yaw) [rad],
    ``R = Rz(yaw) Ry(pitch) Rx(roll)``; positive pitch turns X+ downwards (spec §2.3)."""
    cr, sr = np.cos(att[..., 0]), np.sin(att[..., 0])
    cp, sp = np.cos(att[..., 1]), np.sin(att[..., 1])
    cy, sy = np.cos(att[..., 2]), np.sin(att[..., 2])
    r = np.empty((*att.shape[:-1], 3, 3))
    r[..., 0, 0] = cy * cp
    r[..., 0, 1] = cy * sp * sr - sy * cr
    r[..., 0, 2] = cy * sp * cr + sy * sr
    r[..., 1, 0] = sy * cp
    r[..., 1, 1] = sy * sp * sr + cy * cr
    r[..., 1, 2] = sy * sp * cr - cy * sr
    r[..., 2, 0] = -sp
    r[..., 2, 1] = cp * sr
    r[..., 2, 2] = cp * cr
    return r


@dataclass(frozen=True, slots=True)
class GridPose:
    """Where a grid is placed: LCF origin in GCF [m] and GCF heading ``psi`` [rad]."""

    origin: np.ndarray
    psi: float

    @staticmethod
    def from_ned(pos_ned: np.ndarray, yaw_ned: float) -> GridPose:
        return GridPose(ned_to_enu(pos_ned), heading_from_yaw_ned(yaw_ned))

    @property
    def rot(self) -> np.ndarray:
        """LCF -> GCF rotation (about z by psi)."""
        c, s = np.cos(self.psi), np.sin(self.psi)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    def to_lcf(self, p_gcf: np.ndarray) -> np.ndarray:
        return (np.asarray(p_gcf, float) - self.origin) @ self.rot

    def vec_to_lcf(self, v_gcf: np.ndarray) -> np.ndarray:
        return np.asarray(v_gcf, float) @ self.rot

    def to_gcf(self, p_lcf: np.ndarray) -> np.ndarray:
        return np.asarray(p_lcf, float) @ self.rot.T + self.origin

    def ned_to_lcf(self, p_ned: np.ndarray) -> np.ndarray:
        return self.to_lcf(ned_to_enu(p_ned))

    def lcf_to_ned(self, p_lcf: np.ndarray) -> np.ndarray:
        return enu_to_ned(self.to_gcf(p_lcf))


def ne_to_gcf_xy(ne: np.ndarray) -> np.ndarray:
    """Horizontal (north, east) [m] (..., 2) to GCF (x = east, y = north)."""
    ne = np.asarray(ne, float)
    return ne[..., ::-1]
