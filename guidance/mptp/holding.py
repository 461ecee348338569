"""Fall-backs when no trajectory to the goal is planned (seed 002, 3.3 and 5.4).

Frames/units: (north, east) [m], times [s], courses [rad].

- Holding pattern: when the goal stays covered over the whole horizon (Algorithm 2, line 46),
  the aircraft circles on the inscribed n-gon of auxiliary states (n = 2 pi / |dchi_max|),
  turning one way, until the next replan; each leg is checked against the obstacle envelopes.
- Speed correction (5.4, eqs. 5.76-5.79, ``hold_speed_correction``): flown over, the n-gon's
  states lie on its circumcircle, R_cc = S_n / (2 sin(dchi/2)) with S_n = V dt; an arc between
  two states is S_cc = R_cc dchi > S_n, so the orbit is flown at V_cor = V dV, dV = S_cc / S_n,
  reaching each state after dt (a lap of n states in n dt). The orbit starts on the circle
  tangent to the current course, so no turn is needed to enter it (R_cc >= R is checked).
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
ARC_POINTS = 4  # plan vertices per leg of a speed-corrected orbit (on its circle)
RATE_ONE_LAP_S = 120.0  # a standard-rate (rate-one) turn: 360 deg in 2 min


def speed_correction(dchi: float) -> float:
    """dV = S_cc / S_n for fly-over states turning by ``dchi`` [rad] each (eq. 5.78 with
    2 pi / n = dchi): dchi / (2 sin(dchi / 2))."""
    return dchi / (2.0 * math.sin(0.5 * dchi))


def circumradius_m(cfg: MptpConfig) -> float:
    """R_cc [m] of the holding n-gon with legs S_n = V dt and turns |dchi_max| (eq. 5.76)."""
    return cfg.leg_m / (2.0 * math.sin(0.5 * cfg.course_change_max))


def corrected_speed_mps(cfg: MptpConfig) -> float:
    """V_cor = V dV [m/s] (eq. 5.79)."""
    return cfg.tas_mps * speed_correction(cfg.course_change_max)


def holding_bank(cfg: MptpConfig) -> float:
    """Bank [rad] of the speed-corrected orbit, arctan(V_cor^2 / (g R_cc)) (eq. 5.84)."""
    return math.atan(corrected_speed_mps(cfg) ** 2 / (cfg.g * circumradius_m(cfg)))


def rate_one_dt_s(cfg: MptpConfig, lap_s: float = RATE_ONE_LAP_S) -> float:
    """The time increment dt [s] whose speed-corrected orbit takes ``lap_s`` per lap
    (eqs. 5.80-5.83): R_cc = V_cor lap / (2 pi), dt = 2 R_cc sin(dchi / 2) / V."""
    r_cc = corrected_speed_mps(cfg) * lap_s / (2.0 * math.pi)
    return 2.0 * r_cc * math.sin(0.5 * cfg.course_change_max) / cfg.tas_mps


def corrected_orbit(
    p0: np.ndarray, t0: float, course0: float, n_legs: int, cfg: MptpConfig, side: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n_legs`` legs of the speed-corrected orbit from p0 (course0 [rad] tangent to the
    circle, turning right for ``side`` +1): points on the circle (ARC_POINTS per leg, every
    ARC_POINTS-th a fly-over state), their times (a state every dt, flown at V_cor) and the
    tangent courses."""
    r_cc = circumradius_m(cfg)
    if r_cc < cfg.turn_radius_m:
        raise ValueError(f"holding circle {r_cc:.0f} m is tighter than the turn radius {cfg.turn_radius_m:.0f} m")
    u = np.array([math.cos(course0), math.sin(course0)])
    centre = np.asarray(p0, float) + side * r_cc * np.array([-u[1], u[0]])
    phi0 = math.atan2(*(np.asarray(p0, float) - centre)[::-1])
    frac = np.arange(n_legs * ARC_POINTS + 1) / ARC_POINTS  # legs flown
    phi = phi0 + side * cfg.course_change_max * frac
    pts = centre + r_cc * np.stack([np.cos(phi), np.sin(phi)], 1)
    return pts, t0 + cfg.dt_s * frac, wrap(course0 + side * cfg.course_change_max * frac)


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
    times (N,), courses (N,), or None when a leg would enter the margins (both senses tried).
    With ``hold_speed_correction`` the orbit is the circle flown at V_cor (corrected_orbit)."""
    n_legs = max(1, math.ceil((until - t0) / cfg.dt_s))
    senses = [turning] + [s for s in SENSES if s not in (turning, "both")]
    for sense in senses:
        if cfg.hold_speed_correction:
            orbit = corrected_orbit(np.asarray(p0, float), t0, course0, n_legs, cfg, SENSES[sense][0])
            if not _leg_conflicts(tl, orbit[0], orbit[1]):
                return orbit
            continue
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
