"""Candidate paths: Chen's in-plane cubic, its symmetric variant, copies in rotated planes
(spec §2.1–§2.7).

Shapes live in the UAV xy-plane (x along the reference from the evading point, y lateral) [m].
Candidates are world points, local ENU z-up [m]. All K candidates share one waypoint count N:
shorter paths are padded by repeating their last point (zero-length segments), so that every
downstream array is a dense (K, N, ...) block; ``n_pts`` holds the true counts.

Candidate order: path type (config order) → plane θ_i → offset ω_k, i.e.
``k = (type·P + plane)·W + ω_index``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from avoidance.geometric.config import PATH_TYPES, GeometricConfig
from avoidance.geometric.frames import plane_angles, plane_elevation, uav_frame

SIMPLE, SYMMETRIC = PATH_TYPES.index("simple"), PATH_TYPES.index("symmetric")


def omega_grid(r_thr: float, n_intervals: int, factor: float = 3.2) -> np.ndarray:
    """Lateral offsets ω [m]: linspace(-factor·R, factor·R, l+1) without |ω| <= R, l =
    ``n_intervals`` (eq. 3.6, G5)."""
    if not r_thr > 0:
        raise ValueError(f"threat radius must be > 0, got {r_thr!r}")
    w = np.linspace(-factor * r_thr, factor * r_thr, n_intervals + 1)
    return w[np.abs(w) > r_thr * (1.0 + 1e-12)]


def cubic_shape(dx: float, omega: np.ndarray, x: np.ndarray) -> np.ndarray:
    """y(x) = a x³ + b x², a = -2ω/Δx³, b = 3ω/Δx² (eqs 3.1–3.5, c = 0): zero slope at x = 0,
    extremum ω at x = Δx. ``omega`` (W,), ``x`` (N,) -> (W, N)."""
    t = np.asarray(x, float) / dx
    return np.asarray(omega, float)[:, None] * (3.0 * t**2 - 2.0 * t**3)[None, :]


def shape_abscissae(dx: float, kind: int, step_fraction: float) -> np.ndarray:
    """Sample abscissae [m]: uniform, step <= step_fraction·Δx, over [0, 1.5Δx] (simple) or
    [0, 2Δx] (symmetric, with a sample exactly at the peak Δx)."""
    half = np.linspace(0.0, dx, int(np.ceil(1.0 / step_fraction - 1e-9)) + 1)
    if kind == SYMMETRIC:
        return np.concatenate([half, 2.0 * dx - half[-2::-1]])
    return np.linspace(0.0, 1.5 * dx, int(np.ceil(1.5 / step_fraction - 1e-9)) + 1)


def path_shape(dx: float, omega: np.ndarray, kind: int, step_fraction: float) -> tuple[np.ndarray, np.ndarray]:
    """(x (N,), y (W, N)) of one path type. The symmetric path mirrors the simple path's rise
    about x = Δx (§2.4): it ends at 2Δx with zero slope at both ends."""
    x = shape_abscissae(dx, kind, step_fraction)
    xc = np.minimum(x, 2.0 * dx - x) if kind == SYMMETRIC else x
    return x, cubic_shape(dx, omega, xc)


@dataclass(slots=True)
class CandidateSet:
    """K candidate paths, structure of arrays (world = local ENU z-up, metres, radians).

    - ``points`` (K, N, 3): waypoints, padded with the last point; ``n_pts`` (K,) true counts.
    - ``kind`` (K,): index into ``config.PATH_TYPES``; ``omega`` (K,) [m]; ``theta`` (K,) plane
      rotation [rad]; ``alpha`` (K,) plane elevation [rad]; ``shape_index`` (K,) row of the
      (type, ω) shape the candidate is a copy of.
    - ``shapes``: per configured path type, (x (N_t,), y (W, N_t)) in the UAV plane.
    - ``start`` (3,), ``frame`` (3, 3) UAV -> world, ``dx`` [m] evading point to threat,
      ``radius`` [m] of the main-threat sphere the paths were built around.
    """

    points: np.ndarray
    n_pts: np.ndarray
    kind: np.ndarray
    omega: np.ndarray
    theta: np.ndarray
    alpha: np.ndarray
    shape_index: np.ndarray
    shapes: tuple[tuple[np.ndarray, np.ndarray], ...]
    start: np.ndarray
    frame: np.ndarray
    dx: float
    radius: float

    def __len__(self) -> int:
        return len(self.points)


def generate_candidates(
    start: np.ndarray, x_dir: np.ndarray, dx: float, r_thr: float, cfg: GeometricConfig
) -> CandidateSet:
    """All candidates around a main-threat sphere of radius ``r_thr`` [m] centred on the
    reference at distance ``dx`` [m] from the evading point ``start`` along ``x_dir``. The 2.5·R
    rule is the caller's (see ``avoider``); here only dx > 0 is required."""
    if not (np.isfinite(dx) and dx > 0):
        raise ValueError(f"distance to the threat must be > 0, got {dx!r}")
    start = np.asarray(start, float)
    omega = omega_grid(r_thr, cfg.l, cfg.omega_factor)
    theta = plane_angles(cfg.n_planes)
    frame = uav_frame(x_dir)
    kinds = [PATH_TYPES.index(t) for t in cfg.path_types]
    shapes = tuple(path_shape(dx, omega, k, cfg.x_step_fraction) for k in kinds)
    n_max = max(len(x) for x, _ in shapes)
    W, P = len(omega), len(theta)
    # padded in-plane shapes (types·W, N): repeat each shape's last sample
    sx = np.concatenate(
        [np.broadcast_to(np.pad(x, (0, n_max - len(x)), mode="edge"), (len(y), n_max)) for x, y in shapes]
    )
    sy = np.concatenate([np.pad(y, ((0, 0), (0, n_max - y.shape[1])), mode="edge") for _, y in shapes])
    # local 3D points per (type, plane, ω): R_x(θ)·[x, y, 0] = [x, y cosθ, y sinθ]
    c, s = np.cos(theta), np.sin(theta)
    local = np.stack(
        [
            np.broadcast_to(sx[:, None, :], (len(sx), P, n_max)),
            sy[:, None, :] * c[None, :, None],
            sy[:, None, :] * s[None, :, None],
        ],
        axis=-1,
    )  # (T·W, P, N, 3)
    T = len(kinds)
    local = local.reshape(T, W, P, n_max, 3).transpose(0, 2, 1, 3, 4).reshape(T * P * W, n_max, 3)
    points = start + local @ frame.T
    k_type = np.repeat(np.arange(T), P * W)
    k_plane = np.tile(np.repeat(np.arange(P), W), T)
    k_omega = np.tile(np.arange(W), T * P)
    return CandidateSet(
        points=points,
        n_pts=np.array([len(x) for x, _ in shapes])[k_type],
        kind=np.array(kinds)[k_type],
        omega=omega[k_omega],
        theta=theta[k_plane],
        alpha=plane_elevation(frame, theta)[k_plane],
        shape_index=k_type * W + k_omega,
        shapes=shapes,
        start=start,
        frame=frame,
        dx=float(dx),
        radius=float(r_thr),
    )
