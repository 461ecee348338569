"""The UAV reference frame of the thesis and the rotated candidate planes (spec §2.5, §2.6).

All vectors are in the planner's world frame: local ENU, z up [m]. The UAV frame has its origin
at the evading point, x̂ along the reference, ŷ = normalize(ẑ_world × x̂) (horizontal, left of the
reference) and ẑ = x̂ × ŷ. Plane i is the UAV xy-plane rotated about x̂ by θ_i [rad].
"""

from __future__ import annotations

import numpy as np

UP = np.array([0.0, 0.0, 1.0])
_NORTH = np.array([0.0, 1.0, 0.0])


def unit(v: np.ndarray) -> np.ndarray:
    """``v`` / |v|; raises ValueError for a zero or non-finite vector."""
    v = np.asarray(v, float)
    n = np.linalg.norm(v)
    if not np.isfinite(n) or n < 1e-12:
        raise ValueError(f"cannot normalise vector {v!r}")
    return v / n


def uav_frame(x_dir: np.ndarray) -> np.ndarray:
    """(3, 3) rotation UAV -> world whose columns are x̂, ŷ, ẑ. If x̂ is within ~0.06° of the
    vertical, ŷ falls back to the world y axis (north) made orthogonal to x̂."""
    x = unit(x_dir)
    y = np.cross(UP, x)
    if np.linalg.norm(y) < 1e-3:
        y = _NORTH - (_NORTH @ x) * x
    y = unit(y)
    return np.column_stack([x, y, np.cross(x, y)])


def plane_angles(n_planes: int) -> np.ndarray:
    """θ_i = π·i/(n+1), i = 0..n [rad] (eq. 3.8 plus the original plane)."""
    return np.pi * np.arange(n_planes + 1) / (n_planes + 1)


def plane_elevation(r_wu: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Angle between each rotated plane and the ground, α = arccos|n̂·ẑ_world| [rad], with
    n̂ = R_wu R_x(θ) ẑ."""
    normals = r_wu @ np.stack([np.zeros_like(theta), -np.sin(theta), np.cos(theta)])
    return np.arccos(np.clip(np.abs(normals[2]), 0.0, 1.0))
