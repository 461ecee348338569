"""The goal: a fixed point or a moving one with a predicted track (seed 002, 4.2.2 and 6.4).

Frames/units: (north, east) [m], times [s]. A goal track is piecewise linear in time and held at
its last point afterwards; a fixed goal is a track of one point. Without a prediction the
planner is given the goal's latest position as a fixed goal at every replan (reactive guidance,
which flies a pursuit curve); with a prediction, each expansion aims at the interception point:
the earliest goal state that lies on the aircraft's isochrone, |g(t) - p| = V (t - t_p).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, slots=True)
class GoalTrack:
    """``times`` (K,) [s] increasing and ``points`` (K, 2) (north, east) [m]."""

    times: np.ndarray
    points: np.ndarray

    @classmethod
    def fixed(cls, point) -> GoalTrack:
        return cls(np.zeros(1), np.asarray(point, float).reshape(1, 2))

    @property
    def moving(self) -> bool:
        return len(self.times) > 1

    def at(self, t) -> np.ndarray:
        """Goal position(s) at time(s) t (held before the first and after the last point)."""
        t = np.asarray(t, float)
        return np.stack([np.interp(t, self.times, self.points[:, k]) for k in range(2)], axis=-1)

    def intercept(self, p: np.ndarray, t: np.ndarray, speed: float) -> np.ndarray:
        """Earliest time(s) [s] at which an aircraft leaving p (N, 2) at t (N,) at ``speed``
        [m/s] on a straight line meets the goal (inf when it never does)."""
        p, t = np.atleast_2d(p), np.atleast_1d(np.asarray(t, float))
        if not self.moving:
            return t + np.linalg.norm(self.points[0] - p, axis=1) / speed
        # piece k: g(t') = anchor_k + v_k (t' - tau_k) for t' in [lo_k, hi_k]; held before and after
        lo = np.concatenate([[-np.inf], self.times])
        hi = np.concatenate([self.times, [np.inf]])
        tau = np.concatenate([self.times[:1], self.times])
        anchor = np.vstack([self.points[:1], self.points])
        vel = np.vstack(
            [np.zeros((1, 2)), np.diff(self.points, axis=0) / np.diff(self.times)[:, None], np.zeros((1, 2))]
        )
        best = np.full(len(p), np.inf)
        t_min = float(t.min()) if len(t) else np.inf
        for k in range(len(lo)):
            # a meeting on piece k is at t' >= t (roots >= 0) within [lo_k, hi_k] (1e-9 s slack):
            # pieces that end before every t give none, and once every point has met the goal
            # before a piece starts, it and all later pieces only give later times
            if hi[k] + 1e-9 < t_min:
                continue
            if lo[k] - 1e-9 > best.max():
                break
            q = anchor[k] + vel[k] * (t[:, None] - tau[k]) - p  # g(t + u) - p = q + v u
            a = vel[k] @ vel[k] - speed**2
            b = 2.0 * q @ vel[k]
            c = np.einsum("ij,ij->i", q, q)
            with np.errstate(invalid="ignore", divide="ignore"):
                disc = np.sqrt(b * b - 4 * a * c)
                roots = np.stack([(-b - disc) / (2 * a), (-b + disc) / (2 * a)], 1)
            tt = t[:, None] + roots
            ok = np.isfinite(roots) & (roots >= 0) & (tt >= lo[k] - 1e-9) & (tt <= hi[k] + 1e-9)
            best = np.minimum(best, np.where(ok, tt, np.inf).min(axis=1))
        return best
