"""Time-dependent A* over estimated free state spaces: the partial shortest trajectory map
(seed 002, 4.2.2, Algorithm 2 with Option 1).

Frames/units: (north, east) [m], times [s], courses [rad]. A state is (position, time, course at
arrival). Expanding a state x_in computes EX_free(x_in); its adjacent states are the visible
tangent vertices of EX_obs(x_in), the goal when visible, and the auxiliary turning states, each
kept only when flyable from x_in (course change and leg length, see turning.py). An edge is a
straight leg at constant speed, so arrival times grow along every path (time monotone) and G is
the flight time.

Waiting is an action of its own: from every state but the goal, holding for HOLD_LAPS laps of
the holding orbit (turning.hold_orbit: back at the state on its course, so the legs around it
are unchanged), each kept when the orbit's footprint stays out of the obstacle envelopes over
the whole wait and the wait ends within the planning horizon; holds chain, so any number of laps
up to the horizon is reachable. The cost of a hold is its duration. From the start only when
none of its auxiliary states is flyable (a pocket): elsewhere a wait at an auxiliary state one
leg on stands for it, and waits at the start would spend the expansion cap on the plateau of
equal G + w H that waiting makes (weighted A* takes the longest wait first). The start cannot
anticipate the orbit's first turn: it turns at R into the first leg (turning.flyby_path; with
the orbit's legs of HOLD_SLACK times the shortest that turn fits for every course_change_max in
(0, 90] deg), so a hold there has that turn in its footprint.

Closed list (which states are "the same"): position on a lattice of 1 % of the auxiliary leg,
course to 1 deg, kind, and time: a hold or goal state to 1 % of dt, any other state by the
window of ``dominance_s`` it falls in. So a place and course is expanded once per window, at
its earliest arrival in it: a later arrival in the same window is taken as dominated (what a
hold from the earlier one gives, to within a lap; where no hold fits, it is lost).
The open list is ordered by G + w H (``search_weight`` w, astar.py).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
import shapely
from shapely.geometry import Polygon

from guidance.mptp.astar import astar
from guidance.mptp.config import MptpConfig
from guidance.mptp.goal import GoalTrack
from guidance.mptp.heuristics import GoalAvailability, StaticBound, edh
from guidance.mptp.statespace import FreeSpace, free_space
from guidance.mptp.timeline import ObstacleTimeline
from guidance.mptp.turning import SENSES, admissible, aux_states, flyby_path, hold_lap_s, hold_orbit, min_leg_m
from guidance.mptp.turnmodel import aux_states as fly_over_aux
from guidance.mptp.turnmodel import turn_to
from guidance.mptp.visibility import Boundary, OverBudget, blocked, visible_vertices
from guidance.mptp.waitbound import WaitBound

T = TypeVar("T")
START, VERTEX, AUX, GOAL, HOLD = "start", "vertex", "aux", "goal", "hold"
HOLD_LAPS = (1, 2, 4, 8, 16, 32)  # wait choices per expansion [laps]
TOUCH_M2 = 1.0  # a holding footprint may touch an envelope by this area [m^2]


@dataclass(frozen=True, slots=True)
class State:
    """``side``: for a HOLD state, the sense of its orbit (+1 right, -1 left)."""

    p: tuple[float, float]
    t: float
    course: float
    kind: str
    side: float = 0.0


@dataclass(frozen=True, slots=True)
class Trajectory:
    """Planned states: positions (N, 2) [m], times (N,) [s], courses at arrival (N,) [rad] and
    kinds (start / vertex / aux / goal / hold: the vertices of a holding orbit); ``status``
    "ok", "limit" or "exhausted"; when not "ok" the states are the partial trajectory to the
    expanded state closest to the goal (by the heuristic) that lasts at least ``min_partial_s``
    and has successors, or empty; ``expanded`` EXST; ``start_space`` EX_free of the start state
    (for diagnostics and fall-backs); ``note``: set when the SSPH's reduced visibility graph was
    over its budget (visibility.GRAPH_PAIR_BUDGET) and the search used EDH instead;
    ``start_bank``: the bank the fly-over models' first turn started from (turnmodel.turn_to)."""

    positions: np.ndarray
    times: np.ndarray
    courses: np.ndarray
    kinds: np.ndarray
    status: str
    expanded: int
    runtime_s: float
    start_space: FreeSpace | None  # None when the start state was never expanded
    note: str = ""  # why the search ran without its SSPH bound (its reduced graph over budget)
    start_bank: float = 0.0  # the aircraft's bank at the start [rad] (+ right), where its first turn begins

    @property
    def length_m(self) -> float:
        return float(np.linalg.norm(np.diff(self.positions, axis=0), axis=1).sum()) if len(self.positions) > 1 else 0.0

    @property
    def hold_s(self) -> float:
        """Time spent in planned holds [s]."""
        return float(np.diff(self.times)[self.kinds[1:] == HOLD].sum()) if len(self.times) > 1 else 0.0

    @property
    def holding_turn(self) -> float:
        """Largest course change [rad] turned one way over consecutive auxiliary states: 2 pi
        or more is a holding pattern (5.4)."""
        dchi = np.angle(np.exp(1j * np.diff(self.courses)))
        run, best = 0.0, 0.0
        for d, kind in zip(dchi, self.kinds[1:], strict=False):
            run = run + d if kind == AUX and run * d >= 0 else (d if kind == AUX else 0.0)
            best = max(best, abs(run))
        return best


def default_workspace(points: np.ndarray, cfg: MptpConfig, area: Polygon | None = None) -> Polygon:
    """Bounding box of ``points`` (start and goal positions, (N, 2) [m]) padded by half the
    horizon's range, within ``area`` (the thesis restricts W to the reachable set, 4.1.2)."""
    pad = 0.5 * cfg.tas_mps * cfg.horizon_s
    pts = np.atleast_2d(points)
    lo, hi = pts.min(axis=0) - pad, pts.max(axis=0) + pad
    box = Polygon([(lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]), (lo[0], hi[1])])
    return box if area is None else box.intersection(area)


class SharedWork:
    """What searches from one start time ``t0`` [s] to ``goal`` over ``workspace`` on ``tl``
    share when their configurations differ only in the heuristic: the wait bound (built at its
    first use) and the free space of every expanded state, by its position and time (a free
    space depends on nothing else; such searches expand many of the same states).
    ``reused_cpu_s`` / ``reused_wall_s``: the CPU and wall time [s] that the reused items took
    when first built (what the searches that reused them would have spent without sharing)."""

    def __init__(self, tl: ObstacleTimeline, goal: GoalTrack, cfg: MptpConfig, workspace: Polygon, t0: float):
        self.tl, self.goal, self.cfg, self.w, self.t0 = tl, goal, cfg, workspace, t0
        self.escape_m = 2.0 * float(min_leg_m(cfg.course_change_max, cfg))
        self._wait: tuple[WaitBound, float, float] | None = None
        self._spaces: dict[tuple, tuple[FreeSpace, float, float]] = {}
        self.reused_cpu_s = self.reused_wall_s = 0.0

    def matches(self, tl: ObstacleTimeline, goal: GoalTrack, cfg: MptpConfig, workspace: Polygon, t0: float) -> bool:
        """Whether a search of these arguments may use this shared work."""
        return (
            tl is self.tl
            and t0 == self.t0
            and np.array_equal(goal.times, self.goal.times)
            and np.array_equal(goal.points, self.goal.points)
            and shapely.equals_exact(workspace, self.w, 0.0)
            and cfg.with_(heuristic=self.cfg.heuristic) == self.cfg
        )

    def wait_bound(self) -> WaitBound:
        """The wait bound from t0 to t0 + horizon at the planning speed (waitbound.py)."""
        if self._wait is None:
            cfg, wall, cpu = self.cfg, time.perf_counter(), time.process_time()
            wb = WaitBound(self.tl, self.goal, self.w, self.t0, self.t0 + cfg.horizon_s, cfg.tas_mps, cfg.wait_substeps)
            self._wait = (wb, time.process_time() - cpu, time.perf_counter() - wall)
            return wb
        return self._reused(self._wait)

    def free_space(self, p: np.ndarray, t: float, permanent: bool = False) -> FreeSpace:
        """EX_free of state (p, t) (statespace.free_space with an escape disc reaching two
        minimum legs, or ``permanent``, the SSPH's view, without one)."""
        key = (float(p[0]), float(p[1]), float(t), permanent)
        if key not in self._spaces:
            cfg, wall, cpu = self.cfg, time.perf_counter(), time.process_time()
            escape = 0.0 if permanent else self.escape_m
            fs = free_space(self.tl, p, t, self.w, cfg.tas_mps, cfg.ring_segments, escape, permanent)
            self._spaces[key] = (fs, time.process_time() - cpu, time.perf_counter() - wall)
            return fs
        return self._reused(self._spaces[key])

    def _reused(self, item: tuple[T, float, float]) -> T:
        self.reused_cpu_s += item[1]
        self.reused_wall_s += item[2]
        return item[0]


class _Expander:
    def __init__(
        self,
        tl: ObstacleTimeline,
        goal: GoalTrack,
        cfg: MptpConfig,
        workspace: Polygon,
        turning: str,
        shared: SharedWork,
        bank0: float = 0.0,
    ):
        self.tl, self.goal, self.cfg, self.w, self.turning, self.shared = tl, goal, cfg, workspace, turning, shared
        self.bank0 = bank0  # the aircraft's bank at the start state [rad] (+ right)
        self.start_space: FreeSpace | None = None
        self.availability = GoalAvailability(tl, goal)
        self.static: StaticBound | None = None  # SSPH bound of the start state
        self.note = ""  # set when the SSPH bound is over budget (then EDH alone)
        self.t_end = math.inf  # holds end by this time [s] (the planning horizon)
        self.lap_s = hold_lap_s(cfg)
        self.hold_senses = SENSES[turning][:1] + tuple(x for x in (1.0, -1.0) if x != SENSES[turning][0])

    def __call__(self, s: State):
        v = self.cfg.tas_mps
        p = np.array(s.p)
        fs = self.shared.free_space(p, s.t)
        if self.start_space is None:
            self.start_space = fs
        b = fs.boundary
        t_goal = float(self.goal.intercept(p, np.array([s.t]), v)[0])
        g_pt = self.goal.at(t_goal) if np.isfinite(t_goal) else self.goal.points[-1]
        _, vi = visible_vertices(p[None], b)
        goal_ok = np.isfinite(t_goal) and not blocked(p[None], g_pt[None], b)[0]
        targets = np.vstack([g_pt[None] if goal_ok else np.empty((0, 2)), b.verts[vi]])
        kinds0 = np.array([GOAL] * int(goal_ok) + [VERTEX] * len(vi), dtype="<U6")
        pts, chi, leg, kinds = self._moves(s, b, targets, kinds0)
        waits = s.kind not in (START, GOAL) or (s.kind == START and not np.any(kinds == AUX))
        holds, sides = self._holds(s) if waits else (np.empty(0), np.empty(0))
        pts = np.vstack([pts, np.repeat(p[None], len(holds), 0)])
        chi = np.concatenate([chi, np.full(len(holds), s.course)])
        cost = np.concatenate([leg / v, holds])
        kinds = np.concatenate([kinds, np.full(len(holds), HOLD)])
        sides = np.concatenate([np.zeros(len(pts) - len(holds)), sides])
        times = s.t + cost
        h = self._heuristic(fs, t_goal, pts, times)
        for k in range(len(pts)):
            yield (
                State(
                    (float(pts[k, 0]), float(pts[k, 1])), float(times[k]), float(chi[k]), str(kinds[k]), float(sides[k])
                ),
                float(cost[k]),
                float(h[k]),
            )

    def _moves(
        self, s: State, b: Boundary, targets: np.ndarray, target_kinds: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Flyable successors of s among ``targets`` (N, 2) of ``target_kinds`` (GOAL / VERTEX)
        and its auxiliary states not blocked by the boundary b: positions, courses at arrival
        [rad], flown distances [m] and kinds. Fly-by (simple model, turning.py) or fly-over
        (turnmodel.py) states by ``turn_model``; a fly-over turn from the start begins at the
        aircraft's bank (``bank0``)."""
        cfg, p, start = self.cfg, np.array(s.p), s.kind == START
        if cfg.turn_model == "simple":
            aux_p, _ = aux_states(p, s.course, cfg, self.turning, from_start=start)
            aux_p = aux_p[~blocked(np.repeat(p[None], len(aux_p), 0), aux_p, b)]
            pts = np.vstack([targets, aux_p])
            kinds = np.concatenate([target_kinds, [AUX] * len(aux_p)])
            ok, chi, leg = admissible(p, s.course, pts, cfg, to_goal=kinds == GOAL, from_start=start)
            return pts[ok], chi[ok], leg[ok], kinds[ok]
        bank = self.bank0 if start else 0.0
        ok, _, chi, leg = turn_to(p, s.course, targets, cfg, bank)
        aux_p, aux_chi, aux_leg = fly_over_aux(p, s.course, cfg, SENSES[self.turning], bank)
        free = ~blocked(np.repeat(p[None], len(aux_p), 0), aux_p, b)
        kinds = np.concatenate([target_kinds[ok], [AUX] * int(free.sum())])
        return (
            np.vstack([targets[ok], aux_p[free]]),
            np.concatenate([chi[ok], aux_chi[free]]),
            np.concatenate([leg[ok], aux_leg[free]]),
            kinds,
        )

    def _holds(self, s: State) -> tuple[np.ndarray, np.ndarray]:
        """Admissible waits at s: durations [s] (whole laps of HOLD_LAPS ending by t_end) and the
        sense of each one's orbit, the first sense whose footprint (at the start with the turn
        into its first leg) stays out of the envelopes of every planning interval the wait
        touches."""
        durations = self.lap_s * np.array([k for k in HOLD_LAPS if s.t + k * self.lap_s <= self.t_end + 1e-9])
        if not len(durations):
            return np.empty(0), np.empty(0)
        j0, j1 = int(self.tl.interval(s.t)), int(self.tl.interval(s.t + durations[-1]))
        envs = self.tl.envelopes(np.arange(j0, j1 + 1), np.arange(j0 + 1, j1 + 2))
        last = self.tl.interval(s.t + durations) - j0
        sides = np.zeros(len(durations))
        for side in self.hold_senses:
            lap = hold_orbit(np.array(s.p), s.course, 1, self.cfg, side)
            if s.kind == START:
                lap = np.vstack([lap, flyby_path(lap[:3], s.course, self.cfg.turn_radius_m)])
            footprint = shapely.convex_hull(shapely.multipoints(lap))
            hit = shapely.intersects(envs, footprint)  # only those touched can overlap by area (envs prepared)
            hit[hit] = shapely.area(shapely.intersection(footprint, envs[hit])) > TOUCH_M2
            free_until = int(np.argmax(hit)) - 1 if hit.any() else len(envs) - 1
            sides[(sides == 0) & (last <= free_until)] = side
        return durations[sides != 0], sides[sides != 0]

    def _heuristic(self, fs: FreeSpace, t_goal: float, pts: np.ndarray, times: np.ndarray) -> np.ndarray:
        if self.cfg.heuristic == "dijkstra" or not len(pts):
            return np.zeros(len(pts))
        euclid = np.maximum(
            edh(pts, times, self.goal, self.cfg.tas_mps, self.availability),
            self.shared.wait_bound().arrival(pts, times) - times,
        )
        if self.cfg.heuristic == "edh":
            return euclid
        bound = self._static_bound(fs, t_goal)
        if bound is None:
            return euclid
        static = bound.arrival(pts, times) - times
        return np.where(np.isfinite(static), np.maximum(static, euclid), euclid)

    def _static_bound(self, fs: FreeSpace, t_goal: float) -> StaticBound | None:
        """SSPH bound of the start state for the whole search (one reduced visibility graph per
        replan instead of one per expansion) on its permanent obstacle, to the goal at its
        interception time from the start (see heuristics.py); None, with ``note`` set, when its
        reduced graph is over budget (the search then runs on EDH)."""
        if self.static is None and not self.note:
            cfg = self.cfg
            perm = self.shared.free_space(fs.p_in, fs.t_in, permanent=True)
            tau0 = t_goal if np.isfinite(t_goal) else fs.t_in
            try:
                self.static = StaticBound(perm, self.goal, tau0, fs.t_in + cfg.horizon_s, cfg.tas_mps)
            except OverBudget as err:
                self.note = f"ssph skipped, edh used: its reduced visibility graph tests {err}"
        return self.static


def plan_trajectory(
    tl: ObstacleTimeline,
    p0: np.ndarray,
    t0: float,
    course0: float,
    goal: GoalTrack,
    cfg: MptpConfig,
    workspace: Polygon | None = None,
    turning: str | None = None,
    min_partial_s: float = math.inf,
    shared: SharedWork | None = None,
    bank0: float = 0.0,
) -> Trajectory:
    """Near-time-optimal, time-monotone, flyable trajectory from (p0, t0, course0) to the goal
    (or a partial one, see Trajectory, lasting at least ``min_partial_s`` [s]). ``shared``:
    the wait bound and free spaces of earlier searches of the same timeline, goal, start time,
    workspace and configuration but for the heuristic (see SharedWork; ValueError otherwise).
    ``bank0`` [rad] (+ right): the aircraft's bank at the start, where the fly-over models'
    first turn begins (turnmodel.turn_to; the simple model ignores it)."""
    wall = time.perf_counter()
    p0 = np.asarray(p0, float)
    ends = goal.at(np.array([t0, t0 + cfg.horizon_s]))
    w = workspace if workspace is not None else default_workspace(np.vstack([p0, ends]), cfg, cfg.mission_area)
    if shared is None:
        shared = SharedWork(tl, goal, cfg, w, t0)
    elif not shared.matches(tl, goal, cfg, w, t0):
        raise ValueError("plan_trajectory: shared work of another timeline, goal, start time, workspace or config")
    exp = _Expander(tl, goal, cfg, w, turning or cfg.turning, shared, bank0)
    exp.t_end = t0 + cfg.horizon_s
    q_p, q_t, q_c = 0.01 * cfg.leg_m, 0.01 * cfg.dt_s, math.radians(1.0)

    def key(s: State):
        when = round(s.t / q_t) if s.kind in (HOLD, GOAL) else ("bucket", math.floor(s.t / cfg.dominance_s))
        return round(s.p[0] / q_p), round(s.p[1] / q_p), round(s.course / q_c) % 360, s.kind, when

    start = State((float(p0[0]), float(p0[1])), float(t0), float(course0), START)
    res = astar(
        start,
        exp,
        lambda s: s.kind == GOAL,
        key,
        cfg.max_expansions,
        partial_ok=lambda s: s.t >= t0 + min_partial_s,
        weight=cfg.search_weight,
    )
    path = res.path if res.status == "ok" else res.partial
    positions, times, courses, kinds = _states_with_orbits(path, cfg)
    return Trajectory(
        positions,
        times,
        courses,
        kinds,
        res.status,
        res.expanded,
        time.perf_counter() - wall,
        exp.start_space,
        exp.note,
        bank0,
    )


def _states_with_orbits(path: list[State], cfg: MptpConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Positions, times, courses and kinds of ``path`` with every hold written out as the
    vertices of its orbit (times linear over the hold, the courses of the orbit's legs)."""
    pos: list[np.ndarray] = []
    times: list[np.ndarray] = []
    courses: list[np.ndarray] = []
    kinds: list[np.ndarray] = []
    lap = hold_lap_s(cfg)
    for i, s in enumerate(path):
        if s.kind == HOLD:
            prev = path[i - 1]
            laps = max(1, round((s.t - prev.t) / lap))
            orbit = hold_orbit(np.array(prev.p), prev.course, laps, cfg, s.side)[1:]
            d = np.diff(np.vstack([prev.p, orbit]), axis=0)
            pos.append(orbit)
            times.append(prev.t + (s.t - prev.t) * np.arange(1, len(orbit) + 1) / len(orbit))
            courses.append(np.arctan2(d[:, 1], d[:, 0]))
            kinds.append(np.full(len(orbit), HOLD))
            continue
        pos.append(np.array([s.p]))
        times.append(np.array([s.t]))
        courses.append(np.array([s.course]))
        kinds.append(np.array([s.kind]))
    if not pos:
        return np.empty((0, 2)), np.empty(0), np.empty(0), np.empty(0, str)
    return np.vstack(pos), np.concatenate(times), np.concatenate(courses), np.concatenate(kinds)
