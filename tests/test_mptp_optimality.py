"""MPTP time-optimality with waiting, against an exhaustive search over the same model.

The oracle enumerates every state sequence the search's own successor function allows (legs to
visible vertices, auxiliary states, the goal, and every hold choice), with no expansion cap,
no heuristic, no weight and no dominance: states are the same only when position, course,
kind and time all agree, so it is exact over the model's discretisation up to the time limit
(the planner's own arrival, which bounds the optimum from above). It also gives the true
cost-to-go of every state it visits, which bounds the heuristic from above."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest
import shapely
from shapely.geometry import box

from guidance.mptp.config import MptpConfig
from guidance.mptp.goal import GoalTrack
from guidance.mptp.search import (
    AUX,
    GOAL,
    HOLD,
    HOLD_LAPS,
    START,
    SharedWork,
    State,
    _Expander,
    default_workspace,
    plan_trajectory,
)
from guidance.mptp.timeline import ObstacleTimeline
from guidance.mptp.turning import flyby_path, hold_lap_s, hold_orbit
from sim.core.threats import StormSnapshot

SMALL = MptpConfig(
    safety_single_m=(500.0,) * 3,
    safety_line_m=(500.0,) * 3,
    sigma_front_mps=0.0,
    sigma_back_mps=0.0,
    simplify_tol_m=50.0,
    horizon_s=900.0,
    max_expansions=120,
)


def _instance(seed: int) -> tuple[ObstacleTimeline, np.ndarray, GoalTrack, MptpConfig]:
    """A cell across the direct route that vanishes at a random time (waiting may pay), with a
    random size, offset and goal."""
    rng = np.random.default_rng(seed)
    half_e, half_n = rng.uniform(3_000.0, 7_000.0), rng.uniform(500.0, 1_500.0)
    centre = np.array([rng.uniform(3_500.0, 5_000.0), rng.uniform(-1_000.0, 1_000.0)])
    opens = rng.uniform(120.0, 420.0)
    goal = GoalTrack.fixed([rng.uniform(8_000.0, 10_000.0), rng.uniform(-2_000.0, 2_000.0)])
    cell = box(centre[0] - half_n, centre[1] - half_e, centre[0] + half_n, centre[1] + half_e)
    snaps = [
        StormSnapshot(t, (cell,) if t < opens else (), np.zeros((1 if t < opens else 0, 2)))
        for t in np.arange(0.0, 2 * SMALL.horizon_s + 1.0, 60.0)
    ]
    area = box(-3_000.0, -8_000.0, 13_000.0, 8_000.0)
    cfg = SMALL.with_(mission_area=area)
    return ObstacleTimeline(snaps, cfg, 2 * cfg.horizon_s), np.zeros(2), goal, cfg


class _Oracle:
    """Exact earliest arrival from every state over the successor function of ``exp``, among
    arrivals up to ``t_max`` [s]; ``checks`` (h, true cost-to-go) of every child seen."""

    def __init__(self, exp: _Expander, t_max: float):
        self.exp, self.t_max = exp, t_max
        self.memo: dict[tuple, float] = {}
        self.checks: list[tuple[float, float]] = []

    @staticmethod
    def key(s: State) -> tuple:
        return round(s.p[0], 3), round(s.p[1], 3), round(s.t, 3), round(s.course, 6), s.kind

    def arrival(self, s: State) -> float:
        if s.kind == GOAL:
            return s.t
        k = self.key(s)
        if k not in self.memo:
            best = math.inf
            for child, _cost, h in self.exp(s):
                if child.t > self.t_max + 1e-6:
                    continue
                a = self.arrival(child)
                self.checks.append((h, a - child.t))
                best = min(best, a)
            self.memo[k] = best
        return self.memo[k]


FAST_SEEDS = (3, 5, 10)  # the oracle takes seconds on these, up to ~20 s on the others


@pytest.mark.parametrize("wait_step", [20.0, 60.0])
@pytest.mark.parametrize("seed", [s if s in FAST_SEEDS else pytest.param(s, marks=pytest.mark.slow) for s in range(12)])
def test_planner_arrival_within_two_percent_of_the_exhaustive_optimum(seed, wait_step):
    """Also with the wait bound on one time step per planning interval (``wait_step_min_s`` =
    dt, the coarse bound that small dt get): still admissible and within 2 %."""
    tl, p0, goal, cfg = _instance(seed)
    cfg = cfg.with_(wait_step_min_s=wait_step)
    traj = plan_trajectory(tl, p0, 0.0, 0.0, goal, cfg)
    assert traj.status == "ok"
    arrival = float(traj.times[-1])
    w = default_workspace(np.vstack([p0, goal.at(0.0)]), cfg, cfg.mission_area)
    exp = _Expander(tl, goal, cfg, w, cfg.turning, SharedWork(tl, goal, cfg, w, 0.0))
    exp.t_end = cfg.horizon_s
    oracle = _Oracle(exp, 1.1 * arrival)  # beyond the arrival: more states for the h check
    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 10_000))
    try:
        best = oracle.arrival(State((0.0, 0.0), 0.0, 0.0, START))
    finally:
        sys.setrecursionlimit(limit)
    assert best <= arrival + 1e-6  # the planner's path is one of the oracle's
    assert arrival <= 1.02 * best, f"planner {arrival:.1f} s, exhaustive optimum {best:.1f} s"
    # admissibility (SSPH >= EDH, so EDH too): no heuristic exceeds the true cost-to-go
    h, c2g = np.array([c for c in oracle.checks if math.isfinite(c[1])]).T
    assert len(h) > 10 and np.all(h <= c2g + 1e-6), f"h exceeds the cost-to-go by {np.max(h - c2g):.1f} s"


def test_the_dominance_window_changes_the_search():
    """``dominance_s``: a place and course expanded once per window at its earliest arrival.
    With a window of 1 ms (every arrival time its own state) the capped search spends its
    expansions on the same places at other times, and some instance's plan changes."""
    changed = []
    for seed in range(12):
        tl, p0, goal, cfg = _instance(seed)
        plans = [plan_trajectory(tl, p0, 0.0, 0.0, goal, cfg.with_(dominance_s=d)) for d in (cfg.dominance_s, 1e-3)]
        changed.append(plans[0].status != plans[1].status or not np.array_equal(plans[0].times, plans[1].times))
    assert any(changed)


def test_the_wait_step_sets_the_wait_bound_and_changes_the_search():
    """``wait_step_min_s``: dt split into at most 3 wait-bound steps no shorter than it; at dt
    60 s, 20 s gives 3 steps of 20 s and 60 s one step of 60 s (cells 3x as wide), and some
    instance's search changes."""
    assert [MptpConfig(dt_s=dt).wait_substeps for dt in (30.0, 50.0, 60.0, 100.0)] == [1, 2, 3, 3]
    changed = []
    for seed in range(12):
        tl, p0, goal, cfg = _instance(seed)
        runs = []
        for step in (20.0, 60.0):
            c = cfg.with_(wait_step_min_s=step)
            w = default_workspace(np.vstack([p0, goal.at(0.0)]), c, c.mission_area)
            wait = SharedWork(tl, goal, c, w, 0.0).wait_bound()
            assert wait.tau == pytest.approx(step)
            assert wait.cell == pytest.approx(c.tas_mps * step)
            runs.append(plan_trajectory(tl, p0, 0.0, 0.0, goal, c))
        changed.append(runs[0].expanded != runs[1].expanded or not np.array_equal(runs[0].times, runs[1].times))
    assert any(changed)


def _plug_ahead(half_width_m: float) -> tuple[ObstacleTimeline, GoalTrack, MptpConfig]:
    """A 1 km plug across a mission area 2 half_width_m wide, its south edge 2 km ahead of the
    start, present until 300 s (500 m margins: the band 1.5-3.5 km north is closed before
    300 s); the goal 6 km ahead."""
    cfg = SMALL.with_(mission_area=box(-1_500.0, -half_width_m, 8_000.0, half_width_m))
    plug = box(2_000.0, -6_000.0, 3_000.0, 6_000.0)
    snaps = [
        StormSnapshot(t, (plug,) if t < 300.0 else (), np.zeros((1 if t < 300.0 else 0, 2)))
        for t in np.arange(0.0, 2 * cfg.horizon_s + 1.0, 60.0)
    ]
    return ObstacleTimeline(snaps, cfg, 2 * cfg.horizon_s), GoalTrack.fixed([6_000.0, 0.0]), cfg


def test_a_wait_at_the_start_is_planned_when_only_it_reaches_the_optimum():
    """In a 2 km wide area every auxiliary state of the start (1.1 km aside) is outside it. By
    hand: flown straight, the aircraft reaches the closed band 1500 / 26 = 57.7 s after it
    leaves, so it may leave at 242.3 s at the earliest: three 96.6 s laps of the hold at the
    start (289.7 s), then 6 km straight at 26 m/s (230.8 s), arriving at 520.4 s."""
    tl, goal, cfg = _plug_ahead(1_000.0)
    traj = plan_trajectory(tl, np.zeros(2), 0.0, 0.0, goal, cfg)
    lap = hold_lap_s(cfg)
    assert traj.status == "ok"
    assert traj.times[-1] == pytest.approx(3 * lap + 6_000.0 / cfg.tas_mps, abs=1e-6)
    assert np.all(traj.kinds[1:-1] == HOLD) and traj.hold_s == pytest.approx(3 * lap)


def test_the_start_waits_only_when_none_of_its_auxiliary_states_is_flyable():
    """In a 6 km wide area the start's auxiliary states are flyable: no hold is offered at the
    start (the plan flies to one and waits there); in the 2 km wide one, holds are."""
    for half_width, offered in ((3_000.0, False), (1_000.0, True)):
        tl, goal, cfg = _plug_ahead(half_width)
        w = default_workspace(np.vstack([np.zeros(2), goal.at(0.0)]), cfg, cfg.mission_area)
        exp = _Expander(tl, goal, cfg, w, cfg.turning, SharedWork(tl, goal, cfg, w, 0.0))
        exp.t_end = cfg.horizon_s
        kinds = {child.kind for child, _, _ in exp(State((0.0, 0.0), 0.0, 0.0, START))}
        assert (HOLD in kinds) == offered and (AUX in kinds) != offered, half_width


def test_a_hold_at_the_start_keeps_its_start_turn_out_of_the_envelopes():
    """The start turns at R into the orbit's first leg (45 deg right, 313 m) and passes
    (134, 55) m, 55 m outside the orbit's hull. A cell whose envelope (10 m margin plus the
    inflation, about [113, 427] x [8, 77] m) lies on that turn but off both orbits' hulls: from
    the start the right-hand orbit is refused and every hold within the horizon turns left; from
    an auxiliary state at the same place and course (fly-by, no start turn) it turns right."""
    cfg = SMALL.with_(simplify_tol_m=1.0, safety_single_m=(10.0,) * 3, safety_line_m=(10.0,) * 3)
    cfg = cfg.with_(mission_area=box(-2e3, -2e3, 9e3, 2e3))
    snaps = [
        StormSnapshot(t, (box(140.0, 35.0, 400.0, 50.0),), np.zeros((1, 2)))
        for t in np.arange(0.0, 2 * cfg.horizon_s + 1.0, 60.0)
    ]
    tl = ObstacleTimeline(snaps, cfg, 2 * cfg.horizon_s)
    env = tl.envelopes(np.array([0]), np.array([1]))[0]
    right = hold_orbit(np.zeros(2), 0.0, 1, cfg, 1.0)
    turn = flyby_path(right[:3], 0.0, cfg.turn_radius_m)
    assert env.intersects(shapely.linestrings(turn))
    for side in (1.0, -1.0):
        assert not env.intersects(shapely.convex_hull(shapely.multipoints(hold_orbit(np.zeros(2), 0.0, 1, cfg, side))))
    goal = GoalTrack.fixed([8_000.0, 0.0])
    w = default_workspace(np.vstack([np.zeros(2), goal.at(0.0)]), cfg, cfg.mission_area)
    exp = _Expander(tl, goal, cfg, w, cfg.turning, SharedWork(tl, goal, cfg, w, 0.0))
    exp.t_end = cfg.horizon_s
    laps = sum(k * hold_lap_s(cfg) <= cfg.horizon_s for k in HOLD_LAPS)
    for kind, side in ((START, -1.0), (AUX, 1.0)):
        durations, sides = exp._holds(State((0.0, 0.0), 0.0, 0.0, kind))
        assert len(durations) == laps and np.all(sides == side), kind


@pytest.mark.parametrize("dchi_deg", [1.0, 5.0, 10.0, 20.0, 30.0, 45.0, 60.0, 75.0, 90.0])
def test_the_start_turn_into_a_holding_orbit_fits_its_first_leg(dchi_deg):
    """The start turns at R into the orbit's first leg and must leave room for the fly-by at
    its end (flyby_path raises otherwise) for every course-change limit."""
    cfg = MptpConfig(course_change_max=math.radians(dchi_deg))
    lap = hold_orbit(np.zeros(2), 0.0, 1, cfg, 1.0)
    assert len(flyby_path(lap[:3], 0.0, cfg.turn_radius_m)) > 3
