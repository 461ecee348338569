"""Fall-backs when no trajectory to the goal is planned (seed 002, 3.3 and 5.4).

Frames/units: (north, east) [m], times [s], courses [rad].

- Holding pattern: when the goal stays covered over the whole horizon (Algorithm 2, line 46),
  the aircraft circles on the inscribed n-gon of auxiliary states (n = 2 pi / |dchi_max|),
  turning one way, until the next replan; each leg is checked against the obstacle envelopes.
- Estimated safe area (partial planning): when the search fails, fly straight along the course
  (within the turn limit) whose free straight run in EX_free(x_s) is longest; straight flight in
  EX_free is conflict free by construction.
"""

from __future__ import annotations

import math

import numpy as np

from guidance.mptp.config import MptpConfig
from guidance.mptp.statespace import FreeSpace
from guidance.mptp.timeline import ObstacleTimeline
from guidance.mptp.turning import SENSES, aux_states, wrap
from guidance.mptp.visibility import first_hit

CHECK_STEP_S = 5.0  # spacing of the conflict check along holding legs [s]


def holding_orbit(
    tl: ObstacleTimeline,
    p0: np.ndarray,
    t0: float,
    course0: float,
    until: float,
    cfg: MptpConfig,
    turning: str = "right",
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Auxiliary-state orbit from (p0, t0, course0) lasting until ``until`` [s]: positions (N, 2),
    times (N,), courses (N,), or None when a leg would enter the margins (both senses tried)."""
    n_legs = max(1, math.ceil((until - t0) / cfg.dt_s))
    senses = [turning] + [s for s in SENSES if s not in (turning, "both")]
    for sense in senses:
        pts, times, courses = [np.asarray(p0, float)], [t0], [course0]
        for leg in range(n_legs):
            q, chi = aux_states(pts[-1], courses[-1], cfg, sense, from_start=leg == 0)
            pts.append(q[0])
            times.append(times[-1] + cfg.dt_s)
            courses.append(float(chi[0]))
        p_arr, t_arr = np.array(pts), np.array(times)
        if not _leg_conflicts(tl, p_arr, t_arr):
            return p_arr, t_arr, np.array(courses)
    return None


def _leg_conflicts(tl: ObstacleTimeline, pts: np.ndarray, times: np.ndarray) -> bool:
    k = max(2, math.ceil((times[1] - times[0]) / CHECK_STEP_S) + 1)
    s = np.linspace(0.0, 1.0, k)[None, :, None]
    dense = (pts[:-1, None] * (1 - s) + pts[1:, None] * s).reshape(-1, 2)
    dt = (times[:-1, None] * (1 - s[..., 0]) + times[1:, None] * s[..., 0]).reshape(-1)
    return bool(tl.contains(dense, dt).any())


def safe_area_leg(fs: FreeSpace, course0: float, cfg: MptpConfig, max_len_m: float) -> tuple[np.ndarray, float]:
    """Straight leg inside the estimated safe area: end point and course of the longest free
    radial within the turn limit (courses every 2 deg), capped at ``max_len_m`` [m]."""
    offs = np.deg2rad(np.arange(-90.0, 90.1, 2.0))
    offs = offs[np.abs(offs) <= cfg.course_change_max + 1e-9]
    chi = wrap(course0 + offs)
    far = fs.p_in + max_len_m * np.stack([np.cos(chi), np.sin(chi)], 1)
    frac = np.minimum(first_hit(np.repeat(fs.p_in[None], len(chi), 0), far, fs.boundary), 1.0)
    best = int(np.lexsort((np.abs(offs), -frac))[0])
    return fs.p_in + frac[best] * (far[best] - fs.p_in), float(chi[best])
