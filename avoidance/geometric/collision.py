"""Collision checks of K candidates against J threat spheres, vectorised over
paths × segments × threats (spec §4, G10–G14). World frame local ENU z-up [m], τ [s] from the
evading instant.

The UAV is a sphere of radius ``r_uav`` (stand-in for its box, ``GeometricConfig.r_uav``).
A candidate collides with a threat iff some segment comes closer than R_threat + r_uav:
- ``swept`` (thesis, conservative): distance between the UAV segment and the threat's whole
  collision path (a capsule), whenever either is there; static threats are points;
- ``timed`` (default): distance between UAV and threat centre at the same time τ; both move
  linearly inside each UAV segment, so the minimum has a closed form.
"""

from __future__ import annotations

import numpy as np

from avoidance.geometric.threats import ThreatArrays


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b)


def segseg_distance(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Minimum distance between segments [p1, q1] and [p2, q2] (arrays (..., 3), broadcast),
    Ericson, Real-Time Collision Detection §5.1.9, including degenerate (point) segments."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e, b = _dot(d1, d1), _dot(d2, d2), _dot(d1, d2)
    c, f = _dot(d1, r), _dot(d2, r)
    # A segment is a point only when its length is exactly zero: treating a short segment as a
    # point errs by up to its length. Parallel segments (sin² of their angle ≤ 1e-12) take s = 0.
    a_ok, e_ok = a > 0.0, e > 0.0
    a_s, e_s = np.where(a_ok, a, 1.0), np.where(e_ok, e, 1.0)
    denom = a * e - b * b
    general = np.where(denom > 1e-12 * a_s * e_s, (b * f - c * e) / np.where(denom > 0, denom, 1.0), 0.0)
    s = np.clip(general, 0.0, 1.0)
    t = (b * s + f) / e_s
    s = np.where(t < 0.0, np.clip(-c / a_s, 0.0, 1.0), np.where(t > 1.0, np.clip((b - c) / a_s, 0.0, 1.0), s))
    t = np.clip(t, 0.0, 1.0)
    # degenerate first segment: s = 0, t from projection; degenerate second: t = 0
    s = np.where(a_ok, np.where(e_ok, s, np.clip(-c / a_s, 0.0, 1.0)), 0.0)
    t = np.where(a_ok, np.where(e_ok, t, 0.0), np.where(e_ok, np.clip(f / e_s, 0.0, 1.0), 0.0))
    gap = (p1 + d1 * s[..., None]) - (p2 + d2 * t[..., None])
    return np.sqrt(_dot(gap, gap))


def swept_clearance(points: np.ndarray, threats: ThreatArrays, durations: np.ndarray) -> np.ndarray:
    """(K, N-1, J) distance of every candidate segment to every threat's collision path over
    ``durations`` (J,) [s], minus the grown threat radius [m]."""
    a, b, radius = threats.collision_paths(durations)
    d = segseg_distance(points[:, :-1, None, :], points[:, 1:, None, :], a, b)
    return d - radius


def timed_clearance(
    starts: np.ndarray, vel: np.ndarray, tau0: np.ndarray, dt: np.ndarray, threats: ThreatArrays
) -> np.ndarray:
    """(K, S, J) minimum over each segment's time interval of |UAV − threat centre| minus the
    threat radius grown to the segment end [m]. Segment s of path k starts at ``starts`` (K, S, 3)
    at time ``tau0`` (K, S) and moves at ``vel`` (K, S, 3) for ``dt`` (K, S) seconds."""
    r0 = starts[:, :, None, :] - (threats.p + threats.v * tau0[..., None, None])
    w = vel[:, :, None, :] - threats.v
    ww = _dot(w, w)
    s = np.clip(-_dot(r0, w) / np.where(ww > 0, ww, 1.0), 0.0, dt[..., None])
    gap = r0 + w * s[..., None]
    return np.sqrt(_dot(gap, gap)) - (threats.radius + threats.growth * (tau0 + dt)[..., None])


def with_rejoin_tail(
    points: np.ndarray, seg_vel: np.ndarray, tau: np.ndarray, seg_dt: np.ndarray, tail_vel: np.ndarray, horizon: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Segment arrays (starts, velocities, start times, durations) of K paths followed by the
    reference after the rejoin point, flown at ``tail_vel`` (3,) [m/s] until τ = ``horizon``."""
    end_t = tau[:, -1:]
    return (
        np.concatenate([points[:, :-1], points[:, -1:]], axis=1),
        np.concatenate([seg_vel, np.broadcast_to(tail_vel, (len(points), 1, 3))], axis=1),
        np.concatenate([tau[:, :-1], end_t], axis=1),
        np.concatenate([seg_dt, np.maximum(horizon - end_t, 0.0)], axis=1),
    )


def candidate_clearance(
    points: np.ndarray,
    seg_vel: np.ndarray,
    tau: np.ndarray,
    seg_dt: np.ndarray,
    threats: ThreatArrays,
    mode: str,
    sweep_durations: np.ndarray,
    tail_vel: np.ndarray,
    horizon: float,
) -> np.ndarray:
    """(K, J) smallest clearance [m] (distance minus threat radius) of each candidate to each
    threat; the candidate collides with threat j iff the value is < r_uav.

    ``swept`` uses the collision paths over ``sweep_durations`` (J,) [s]; ``timed`` checks the
    candidate and then the reference after the rejoin (``tail_vel``) up to τ = ``horizon`` [s]."""
    if len(threats) == 0:
        return np.zeros((len(points), 0))
    if mode == "swept":
        return swept_clearance(points, threats, sweep_durations).min(axis=1)
    if mode == "timed":
        return timed_clearance(*with_rejoin_tail(points, seg_vel, tau, seg_dt, tail_vel, horizon), threats).min(axis=1)
    raise ValueError(f"unknown dynamic mode {mode!r}")
