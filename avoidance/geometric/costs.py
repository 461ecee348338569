"""Raw cost terms of K candidates (spec §5.1–§5.6, G1–G3, G8, G9, G15–G19), all vectorised.

Frames/units: points (K, N, 3) local ENU z-up [m] (potential energy uses z up), velocities [m/s],
times [s], energy [J], power [W]. Paths are padded by repeating their last point with the last
velocity (see ``kinematics``), which adds nothing to sums; means use the ``n_pts`` mask.
"""

from __future__ import annotations

import numpy as np

from avoidance.geometric.config import GeometricConfig, VehicleParams


def waypoint_mask(n_pts: np.ndarray, n: int) -> np.ndarray:
    """(K, N) true on real (not padding) waypoints."""
    return np.arange(n)[None, :] < n_pts[:, None]


def energy(points: np.ndarray, wp_vel: np.ndarray, veh: VehicleParams, rho: float, g: float) -> np.ndarray:
    """E_T = Σ|ΔE_M| + Σ E_D [J] (eqs 4.1–4.5): E_M = ½ m |v|² + m g z, and per segment
    E_D = ½ C_D ρ A_e |Δp| · |v_{i+1} + v_i|² / 2 (the factor kept literally, spec §5.1)."""
    e_m = 0.5 * veh.mass * np.einsum("kni,kni->kn", wp_vel, wp_vel) + veh.mass * g * points[..., 2]
    e1 = np.abs(np.diff(e_m, axis=1)).sum(axis=1)
    vsum = wp_vel[:, 1:] + wp_vel[:, :-1]
    seg_len = np.linalg.norm(np.diff(points, axis=1), axis=-1)
    e2 = (
        0.5
        * veh.drag_coefficient
        * rho
        * veh.effective_area
        * (seg_len * np.einsum("kni,kni->kn", vsum, vsum) / 2.0).sum(axis=1)
    )
    return e1 + e2


def smoothness(x: np.ndarray, y: np.ndarray, method: str = "curvature") -> np.ndarray:
    """Smoothness of W in-plane shapes sharing abscissae ``x`` (N,), ``y`` (W, N) [m]:
    ``curvature`` ∫κ² dx (derivatives against the sample index, trapezoid over x, G18),
    ``std`` population std of y, ``second_derivative`` mean |y''| (eqs 4.6–4.9)."""
    if method == "std":
        return np.std(y, axis=1)
    if method == "second_derivative":
        return np.abs(np.gradient(np.gradient(y, x, axis=1), x, axis=1)).mean(axis=1)
    if method != "curvature":
        raise ValueError(f"unknown smoothness method {method!r}")
    xs = np.broadcast_to(x, y.shape)
    x1, y1 = np.gradient(xs, axis=1), np.gradient(y, axis=1)
    x2, y2 = np.gradient(x1, axis=1), np.gradient(y1, axis=1)
    kappa = np.abs(x2 * y1 - x1 * y2) / (x1**2 + y1**2) ** 1.5
    return np.trapezoid(kappa**2, x, axis=1)


def rotation_penalty(s: np.ndarray, alpha: np.ndarray, k_p: float) -> np.ndarray:
    """S_rp = S (1 + k_p |sin α|) (eq. 4.10), α the plane elevation [rad]."""
    return s * (1.0 + k_p * np.abs(np.sin(alpha)))


def sample_threat_paths(start: np.ndarray, end: np.ndarray, step: float, min_samples: int) -> np.ndarray:
    """(J, S, 3) uniform samples of J collision paths, S = max(min_samples, longest/step + 1) (G15)."""
    longest = float(np.linalg.norm(end - start, axis=1).max(initial=0.0))
    n = max(min_samples, int(np.ceil(longest / step)) + 1)
    u = np.linspace(0.0, 1.0, n)
    return start[:, None, :] + (end - start)[:, None, :] * u[None, :, None]


def closeness(
    points: np.ndarray, n_pts: np.ndarray, samples: np.ndarray, radii: np.ndarray, cfg: GeometricConfig
) -> np.ndarray:
    """Closeness to moving objects M (eqs 4.11–4.12) of K paths to J sampled collision paths
    ``samples`` (J, S, 3) of threats with ``radii`` (J,) [m]: per threat, nearest-sample distance
    of every waypoint minus the radius (clamped to ``cmo_min_distance``), f = 1/(k1·mean + k2·min);
    M = ½ max_j f + ½ mean_j f. No threat -> 0 (G16)."""
    if len(samples) == 0:
        return np.zeros(len(points))
    K, N, _ = points.shape
    J, S, _ = samples.shape
    a, b = points.reshape(-1, 3), samples.reshape(-1, 3)
    sq = (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * (a @ b.T)  # |a − b|², (K·N, J·S)
    d = np.sqrt(np.maximum(sq.reshape(K, N, J, S).min(axis=-1), 0.0)) - radii
    d = np.maximum(d, cfg.cmo_min_distance)
    mask = waypoint_mask(n_pts, points.shape[1])[..., None]
    mean = np.where(mask, d, 0.0).sum(axis=1) / n_pts[:, None]
    dmin = np.where(mask, d, np.inf).min(axis=1)
    f = 1.0 / (cfg.k1 * mean + cfg.k2 * dmin)  # (K, J)
    return 0.5 * f.max(axis=1) + 0.5 * f.mean(axis=1)


def hover_power(
    seg_vel: np.ndarray, n_pts: np.ndarray, veh: VehicleParams, rho: float, g: float, literal_ki: bool = False
) -> np.ndarray:
    """Sum over segments of the rotor power [W] for the segment's vertical speed (eqs 4.15–4.23,
    G19; a sum of watts, as in the thesis). Diagnostic only. ``literal_ki`` applies k_i on top of
    the empirical descent fit as the thesis writes it (counting it twice)."""
    W = veh.mass * g
    A = veh.n_rotors * np.pi * veh.blade_radius**2
    sigma = veh.blades_per_rotor * veh.blade_chord / (np.pi * veh.blade_radius)
    p0 = rho * A * veh.v_tip**3 * sigma * veh.blade_cd / 8.0
    ki, v_ih = veh.k_induced, np.sqrt(W / (2.0 * rho * A))
    vy = seg_vel[..., 2]
    climb = W * (vy - ki * vy / 2.0 + (ki / 2.0) * np.sqrt(vy**2 + 2.0 * W / (rho * A)))
    x = vy / v_ih
    v_id = v_ih * (ki - 1.125 * x - 1.372 * x**2 - 1.718 * x**3 - 0.655 * x**4)
    mild = W * (vy + (ki if literal_ki else 1.0) * v_id)
    steep = W * (vy - (ki / 2.0) * (vy + np.sqrt(np.maximum(vy**2 - 2.0 * W / A / rho, 0.0))))
    hover = ki * W * v_ih
    p = np.where(vy > 0, climb, np.where(vy == 0, hover, np.where(x >= -2.0, mild, steep))) + p0
    real = np.arange(seg_vel.shape[1])[None, :] < (n_pts[:, None] - 1)
    return np.where(real, p, 0.0).sum(axis=1)
