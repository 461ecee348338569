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
the aircraft turns at R from the start until it points at the next state, which the fly-by
reserve leaves room for.
"""

from __future__ import annotations

import math

import numpy as np

from guidance.mptp.config import MptpConfig

SENSES = {"both": (1.0, -1.0), "right": (1.0,), "left": (-1.0,)}


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


def admissible(
    p: np.ndarray, course: float, targets: np.ndarray, cfg: MptpConfig, to_goal: np.ndarray | bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Which targets (N, 2) may follow a state at p with ``course``: (mask, course at arrival,
    leg length [m])."""
    leg = np.linalg.norm(targets - p, axis=1)
    chi = bearing(p, targets)
    dchi = wrap(chi - course)
    ok = (np.abs(dchi) <= cfg.course_change_max + 1e-9) & (leg >= min_leg_m(dchi, cfg, to_goal))
    return ok, chi, leg


def aux_states(p: np.ndarray, course: float, cfg: MptpConfig, turning: str) -> tuple[np.ndarray, np.ndarray]:
    """Auxiliary states of one state: positions (k, 2) and courses (k,) for the turning senses."""
    chi = np.array([course + s * cfg.course_change_max for s in SENSES[turning]])
    pts = p + cfg.leg_m * np.stack([np.cos(chi), np.sin(chi)], 1)
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
        # turn towards the target: at the start (no anticipation) or after a fly-by exit
        side = np.sign(_cross(_unit(chi), target - pos))
        turned = 0.0
        while abs(wrap(bearing(pos, target) - chi)) > step and turned < 2 * math.pi:
            pos, chi = _arc_step(pos, chi, side, radius, step)
            out.append(pos)
            turned += step
        if turned >= 2 * math.pi:
            raise ValueError(f"state {i} lies inside the turning circle")
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
