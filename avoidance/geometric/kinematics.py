"""Velocity profile and timing of candidate paths (spec §3.2, G7, G8, G31).

Every straight segment is flown at ``v_cruise`` [m/s] along its direction; if |v_z| (world z,
up) exceeds ``max_roc`` the velocity is scaled down keeping its direction (climb and descent).
Arrays: points (K, N, 3) [m] padded by repeating the last point; padded segments have zero
length, take the last real segment's velocity and last zero time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(slots=True)
class Kinematics:
    """``seg_vel`` (K, N-1, 3) [m/s], ``seg_len`` (K, N-1) [m], ``seg_dt`` (K, N-1) [s],
    ``tau`` (K, N) time at each waypoint from the evading point [s], ``T`` (K,) flight time [s],
    ``wp_vel`` (K, N, 3) per-waypoint velocity, the last one repeated (G8)."""

    seg_vel: np.ndarray
    seg_len: np.ndarray
    seg_dt: np.ndarray
    tau: np.ndarray
    T: np.ndarray
    wp_vel: np.ndarray


def capped_velocity(direction: np.ndarray, v_cruise: float, max_roc: float) -> np.ndarray:
    """Velocity along unit ``direction`` (..., 3) at ``v_cruise``, scaled so that |v_z| <= max_roc."""
    v = v_cruise * direction
    vz = np.abs(v[..., 2:3])
    return v * np.minimum(1.0, max_roc / np.maximum(vz, 1e-300))


def path_kinematics(points: np.ndarray, n_pts: np.ndarray, v_cruise: float, max_roc: float) -> Kinematics:
    """Segment velocities, lengths, times and waypoint timestamps of K padded paths."""
    d = np.diff(points, axis=1)
    seg_len = np.linalg.norm(d, axis=-1)
    real = np.arange(d.shape[1])[None, :] < (n_pts[:, None] - 1)
    if np.any(real & (seg_len <= 0.0)):
        raise ValueError("candidate path has a zero-length segment before its end")
    direction = d / np.where(real, seg_len, 1.0)[..., None]
    last = np.minimum(np.arange(d.shape[1])[None, :], n_pts[:, None] - 2)  # padded -> last real
    direction = np.take_along_axis(direction, last[..., None], axis=1)
    seg_vel = capped_velocity(direction, v_cruise, max_roc)
    seg_dt = np.where(real, seg_len / np.linalg.norm(seg_vel, axis=-1), 0.0)
    tau = np.concatenate([np.zeros((len(points), 1)), np.cumsum(seg_dt, axis=1)], axis=1)
    wp_vel = np.concatenate([seg_vel, seg_vel[:, -1:]], axis=1)
    return Kinematics(seg_vel, seg_len, seg_dt, tau, tau[:, -1], wp_vel)
