"""Nonholonomic turning flight (seed 002, ch. 5): auxiliary states and fly-by geometry.

Frames/units: (north, east) [m]; courses [rad] from north, positive towards east; a right turn
increases the course. Turn radius R = V^2 / (g tan(bank_max)) (eq. 5.67).

Simple auxiliary states (5.1): from a state with course chi the aircraft may change course by at
most |dchi_max|; an auxiliary state lies on the new course chi +- dchi_max at the leg distance
LD = V dt. Consecutive auxiliary states turning one way form the inscribed n-gon of a circular
holding pattern (5.4, n = 2 pi / dchi_max).

Flyability: every state is flown as a fly-by with the minimum radius; its turn anticipation is
R tan(|dchi|/2) on both adjacent legs (the minimum stabilisation distance of Table 5.1). A leg is
admissible when it holds the anticipation of the turn at its start plus the largest possible
one at its end (a leg to the goal has no turn at its end). The start state cannot anticipate:
the aircraft turns at R from its current course until it points at the next state, which must
therefore lie outside that turning circle, and arrives on the turn's exit course.

Holding (waiting) at a state: a regular n-gon (n = ceil(2 pi / |dchi_max|), turn 2 pi / n at
every vertex) that leaves the state turning one way and returns to it on its arrival course, so
the legs before and after are flown as if there had been no wait. Its leg is HOLD_SLACK times
the shortest one whose fly-bys fit (both ends anticipate a turn of up to |dchi_max|), flown at V.
"""

from __future__ import annotations

import math

import numpy as np

from guidance.mptp.config import MptpConfig

SENSES = {"both": (1.0, -1.0), "right": (1.0,), "left": (-1.0,)}
HOLD_SLACK = 2.0  # holding leg / the shortest flyable one


def wrap(a):
    """Angle(s) wrapped to (-pi, pi] [rad]."""
    return np.pi - np.mod(np.pi - np.asarray(a, float), 2 * np.pi)


def bearing(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Course [rad] from p to q (north = 0, east = +pi/2)."""
    d = np.asarray(q, float) - np.asarray(p, float)
    return np.arctan2(d[..., 1], d[..., 0])


def min_leg_m(dchi: np.ndarray | float, cfg: MptpConfig, to_goal: np.ndarray | bool = False) -> np.ndarray:
    """Shortest admissible leg [m] after a course change ``dchi`` [rad]."""
    reserve = np.where(to_goal, 0.0, math.tan(0.5 * cfg.course_change_max))
    return cfg.turn_radius_m * (np.tan(0.5 * np.abs(dchi)) + reserve)


def start_turn(
    p: np.ndarray, course: float, targets: np.ndarray, radius: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The turn from a state that cannot anticipate (the start): at ``radius`` [m] from p
    towards the side of each target (N, 2) until pointing at it, then straight.

    Returns (reachable: target outside the turning circle, signed turn [rad] (+ = right), course
    at the turn's exit = at arrival [rad], straight length after the turn [m]); the flown
    distance is radius * |turn| + straight."""
    u = np.array([math.cos(course), math.sin(course)])
    d0 = np.asarray(targets, float) - p
    side = np.where(u[0] * d0[:, 1] - u[1] * d0[:, 0] >= 0.0, 1.0, -1.0)
    centre = p + radius * side[:, None] * np.array([-u[1], u[0]])
    d = targets - centre
    dist = np.linalg.norm(d, axis=1)
    reachable = dist >= radius
    ratio = np.minimum(radius / np.maximum(dist, 1e-12), 1.0)
    chi = wrap(np.arctan2(d[:, 1], d[:, 0]) + side * (0.5 * math.pi - np.arccos(ratio)))
    turn = wrap(chi - course)
    turn = np.where(side * turn >= -1e-9, turn, turn + side * 2 * math.pi)
    straight = np.sqrt(np.maximum(dist**2 - radius**2, 0.0))
    return reachable, turn, chi, straight


def admissible(
    p: np.ndarray,
    course: float,
    targets: np.ndarray,
    cfg: MptpConfig,
    to_goal: np.ndarray | bool = False,
    from_start: bool = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Which targets (N, 2) may follow a state at p with ``course``: (mask, course at arrival
    [rad], flown distance [m]).

    After a fly-by (``from_start`` False) the leg is straight on the bearing and must hold the
    turn's anticipation plus the reserve for the next one. From the start the aircraft turns at
    R from ``course`` (:func:`start_turn`): the target must lie outside the turning circle, the
    turn within the course-change limit, and the straight part after it must hold the reserve;
    the course at arrival is the turn's exit course."""
    reserve = np.where(to_goal, 0.0, math.tan(0.5 * cfg.course_change_max)) * cfg.turn_radius_m
    if from_start:
        reachable, turn, chi, straight = start_turn(p, course, targets, cfg.turn_radius_m)
        ok = reachable & (np.abs(turn) <= cfg.course_change_max + 1e-6) & (straight >= reserve)
        return ok, chi, cfg.turn_radius_m * np.abs(turn) + straight
    leg = np.linalg.norm(targets - p, axis=1)
    chi = bearing(p, targets)
    dchi = wrap(chi - course)
    ok = (np.abs(dchi) <= cfg.course_change_max + 1e-9) & (leg >= min_leg_m(dchi, cfg, to_goal))
    return ok, chi, leg


def aux_states(
    p: np.ndarray, course: float, cfg: MptpConfig, turning: str, from_start: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Auxiliary states of one state: positions (k, 2) and courses (k,) for the turning senses,
    a flight of LD on the course chi +- dchi_max. After a fly-by the leg is straight on it; from
    the start (no anticipation) the aircraft first turns by dchi_max at R, then flies straight
    for the rest of LD."""
    sides = np.array(SENSES[turning])
    chi = course + sides * cfg.course_change_max
    if not from_start:
        return p + cfg.leg_m * np.stack([np.cos(chi), np.sin(chi)], 1), wrap(chi)
    r, th = cfg.turn_radius_m, cfg.course_change_max
    mid = course + 0.5 * sides * th
    arc = 2.0 * r * math.sin(0.5 * th) * np.stack([np.cos(mid), np.sin(mid)], 1)
    pts = p + arc + (cfg.leg_m - r * th) * np.stack([np.cos(chi), np.sin(chi)], 1)
    return pts, wrap(chi)


def flyby_path(points: np.ndarray, course0: float, radius: float, step_deg: float = 1.0) -> np.ndarray:
    """The curve flown through ``points`` (N, 2) from ``course0`` with turns of ``radius`` [m]:
    a turn from the start until pointing at the next state, then a fly-by arc at every interior
    state. Raises ValueError when a turn does not fit its legs."""
    step = math.radians(step_deg)
    out = [points[0]]
    pos, chi = points[0].astype(float), float(course0)
    for i in range(1, len(points)):
        target = points[i]
        if i == 1:  # the start turns towards the first state without anticipation
            reachable, turn, chi_exit, _ = start_turn(pos, chi, target[None], radius)
            if not reachable[0]:
                raise ValueError("state 1 lies inside the turning circle")
            n = int(abs(turn[0]) / step) + 1
            for _ in range(n):
                pos, chi = _arc_step(pos, chi, math.copysign(1.0, turn[0]), radius, abs(turn[0]) / n)
                out.append(pos)
            chi = float(chi_exit[0])
        if i == len(points) - 1:
            out.append(target)
            break
        chi_in, chi_out = bearing(pos, target), bearing(target, points[i + 1])
        dchi = float(wrap(chi_out - chi_in))
        lead = radius * math.tan(0.5 * abs(dchi))
        leg_in = float(np.linalg.norm(target - pos))
        if lead > leg_in + 1e-6 or lead > np.linalg.norm(points[i + 1] - target) + 1e-6:
            raise ValueError(f"the fly-by at state {i} does not fit its legs")
        chi = float(chi_in)
        pos = target - lead * _unit(chi)
        out.append(pos)
        n = int(abs(dchi) / step)
        for _ in range(n):
            pos, chi = _arc_step(pos, chi, np.sign(dchi), radius, abs(dchi) / n)
            out.append(pos)
    return np.array(out)


def _unit(chi: float) -> np.ndarray:
    return np.array([math.cos(chi), math.sin(chi)])


def _cross(a: np.ndarray, b: np.ndarray) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def _arc_step(pos: np.ndarray, chi: float, side: float, radius: float, dth: float) -> tuple[np.ndarray, float]:
    """Advance along a circle of ``radius`` by the angle ``dth``; side +1 = right turn."""
    chord = 2.0 * radius * math.sin(0.5 * dth)
    mid = chi + side * 0.5 * dth
    return pos + chord * _unit(mid), chi + side * dth


def hold_sides(cfg: MptpConfig) -> int:
    """Number of legs n of one holding lap."""
    return math.ceil(2 * math.pi / cfg.course_change_max - 1e-9)


def hold_lap_s(cfg: MptpConfig) -> float:
    """Duration of one holding lap [s]: n legs of HOLD_SLACK * 2 R tan(|dchi_max| / 2) at V."""
    leg = HOLD_SLACK * 2.0 * cfg.turn_radius_m * math.tan(0.5 * cfg.course_change_max)
    return hold_sides(cfg) * leg / cfg.tas_mps


def hold_orbit(p: np.ndarray, course: float, laps: int, cfg: MptpConfig, side: float) -> np.ndarray:
    """Vertices (n * laps + 1, 2) [m] of ``laps`` holding laps from p (course ``course`` [rad]
    at p, turning right for ``side`` +1, left for -1); first and last are p, flown at V."""
    n = hold_sides(cfg)
    leg = hold_lap_s(cfg) * cfg.tas_mps / n
    chi = course + side * 2 * math.pi / n * np.arange(1, n + 1)
    lap = np.vstack([np.zeros((1, 2)), np.cumsum(leg * np.stack([np.cos(chi), np.sin(chi)], 1), axis=0)])
    lap[-1] = 0.0  # closes exactly
    return np.asarray(p, float) + np.vstack([lap[:1], np.tile(lap[1:], (laps, 1))])
