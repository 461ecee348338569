"""Plan keeping between replans: is the plan being flown still clear, and is it being flown?

Frames/units: (north, east) [m] on the ground, times in sim seconds [s]; the timeline's shapes
are in its air-mass frame (wind.py), so plan positions are moved into it at their times.

A replan keeps the current plan instead of a new one when the current plan reaches the goal,
the aircraft is within ``tolerance_m`` of where the plan has it now (so the plan's times still
hold), the rest of the plan is clear of the new nowcast's obstacle, and the new plan does not
arrive earlier by more than ``keep_slack`` of the remaining flight time (planner.py). Without
this every replan flies the first of many near-equal plans the search meets: with waiting they
differ in where and how the aircraft waits, and each change of plan wastes flight.

Clear = the plan's positions in planning interval j stay out of the envelope E_j of that interval
(timeline.py: E_j holds the obstacle at every time of the interval), the test the search's legs
pass by construction (statespace.py); legs run along E_j's edges between its tangent vertices, so
a position counts as inside only deeper than ``TOUCH_M``. The envelopes' extra margin grows
with the planning speed (the turn cut, margins.turn_cut_m), and each replan plans at a new
airspeed estimate: a kept plan is tested at the margins it was planned with, so it may lie inside
the new envelopes by as much as their extra margin grew since (:func:`extra_growth_m`).
"""

from __future__ import annotations

import numpy as np
import shapely

from guidance.mptp.config import MptpConfig
from guidance.mptp.margins import turn_cut_m
from guidance.mptp.timeline import ObstacleTimeline
from guidance.mptp.wind import to_air
from sim.core.plan import Plan

TOUCH_M = 1.0  # a position closer than this to an envelope's boundary is outside it [m]
SAMPLE_S = 2.0  # the plan is tested at its vertices and every this many seconds [s]


def position_at(plan: Plan, t: float | np.ndarray) -> np.ndarray:
    """Where ``plan`` has the aircraft at time(s) ``t`` [s]: (north, east) [m], shape (2,) for
    one time and (n, 2) for n times, linear in time between its vertices (held at its ends)."""
    return np.stack([np.interp(t, plan.times, plan.positions[:, k]) for k in range(2)], axis=-1)


def remaining_clear(plan: Plan, tl: ObstacleTimeline, t: float, wind_ne: np.ndarray, touch_m: float = TOUCH_M) -> bool:
    """Whether the plan from time ``t`` [s] to its end stays out of ``tl``'s envelopes: its
    positions every ``SAMPLE_S`` (and at its vertices), each tested against the envelope of the
    planning interval it is flown in (``wind_ne``: the timeline frame's drift [m/s]); a position
    closer than ``touch_m`` [m] to an envelope's boundary is outside it."""
    times = np.asarray(plan.times, float)
    if times[-1] <= t:
        return True
    knots = np.unique(np.concatenate([np.arange(t, times[-1], SAMPLE_S), times[times > t]]))
    ne = position_at(plan, knots)
    ne = to_air(ne, knots, wind_ne, tl.t_issue) if np.any(wind_ne) else ne
    j = tl.interval(knots)
    for level in np.unique(j):
        env = tl.envelope(int(level))
        pts = ne[j == level]
        inside = shapely.contains_xy(env, pts[:, 0], pts[:, 1])
        if inside.any() and np.any(shapely.distance(shapely.points(pts[inside]), env.boundary) > touch_m):
            return False
    return True


def extra_growth_m(plan: Plan, tl: ObstacleTimeline, cfg: MptpConfig) -> float:
    """How much deeper [m] ``tl``'s envelopes reach than those ``plan`` was planned on, through
    the speed-dependent extra margin alone: ``tl.extra_m`` minus the extra margin of ``cfg`` at
    the plan's planning speed (its ``tas_mps`` diagnostic [m/s]); 0 when it did not grow."""
    tas = float(plan.diagnostics.get("tas_mps", cfg.tas_mps))
    planned = cfg.with_(tas_mps=tas)
    return max(0.0, tl.extra_m - (planned.simplify_tol_m + turn_cut_m(planned)))
