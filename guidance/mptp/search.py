"""Time-dependent A* over estimated free state spaces: the partial shortest trajectory map
(seed 002, 4.2.2, Algorithm 2 with Option 1).

Frames/units: (north, east) [m], times [s], courses [rad]. A state is (position, time, course at
arrival). Expanding a state x_in computes EX_free(x_in); its adjacent states are the visible
tangent vertices of EX_obs(x_in), the goal when visible, and the auxiliary turning states, each
kept only when flyable from x_in (course change and leg length, see turning.py). An edge is a
straight leg at constant speed, so arrival times grow along every path (time monotone) and G is
the flight time. States are "the same" (closed list) on a lattice of 1 % of the auxiliary leg,
1 % of dt and 1 deg of course: revisiting a place later is a different state, which lets the
search wait by circling (holding patterns) and keeps it resolution complete in time.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from shapely.geometry import Polygon

from guidance.mptp.astar import astar
from guidance.mptp.config import MptpConfig
from guidance.mptp.goal import GoalTrack
from guidance.mptp.heuristics import GoalAvailability, StaticPaths, edh
from guidance.mptp.statespace import FreeSpace, free_space
from guidance.mptp.timeline import ObstacleTimeline
from guidance.mptp.turning import admissible, aux_states, min_leg_m
from guidance.mptp.visibility import blocked, visible_vertices

START, VERTEX, AUX, GOAL = "start", "vertex", "aux", "goal"


@dataclass(frozen=True, slots=True)
class State:
    p: tuple[float, float]
    t: float
    course: float
    kind: str


@dataclass(frozen=True, slots=True)
class Trajectory:
    """Planned states: positions (N, 2) [m], times (N,) [s], courses at arrival (N,) [rad] and
    kinds (start / vertex / aux / goal); ``status`` "ok", "limit" or "exhausted"; when not "ok"
    the states are the partial trajectory to the expanded state closest to the goal (by the
    heuristic) that lasts at least ``min_partial_s`` and has successors, or empty; ``expanded``
    EXST; ``start_space`` EX_free of the start state (for diagnostics and fall-backs)."""

    positions: np.ndarray
    times: np.ndarray
    courses: np.ndarray
    kinds: np.ndarray
    status: str
    expanded: int
    runtime_s: float
    start_space: FreeSpace | None  # None when the start state was never expanded

    @property
    def length_m(self) -> float:
        return float(np.linalg.norm(np.diff(self.positions, axis=0), axis=1).sum()) if len(self.positions) > 1 else 0.0

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


class _Expander:
    def __init__(self, tl: ObstacleTimeline, goal: GoalTrack, cfg: MptpConfig, workspace: Polygon, turning: str):
        self.tl, self.goal, self.cfg, self.w, self.turning = tl, goal, cfg, workspace, turning
        self.start_space: FreeSpace | None = None
        self.escape_m = 2.0 * float(min_leg_m(cfg.course_change_max, cfg))
        self.availability = GoalAvailability(tl, goal)
        self.static: StaticPaths | None = None  # SSPH graph of the start state (fixed goal)

    def __call__(self, s: State):
        cfg, v = self.cfg, self.cfg.tas_mps
        p = np.array(s.p)
        fs = free_space(self.tl, p, s.t, self.w, v, cfg.ring_segments, self.escape_m)
        if self.start_space is None:
            self.start_space = fs
        b = fs.boundary
        t_goal = float(self.goal.intercept(p, np.array([s.t]), v)[0])
        g_pt = self.goal.at(t_goal) if np.isfinite(t_goal) else self.goal.points[-1]
        _, vi = visible_vertices(p[None], b)
        aux_p, _ = aux_states(p, s.course, cfg, self.turning, from_start=s.kind == START)
        aux_p = aux_p[~blocked(np.repeat(p[None], len(aux_p), 0), aux_p, b)]
        goal_ok = np.isfinite(t_goal) and not blocked(p[None], g_pt[None], b)[0]
        pts = np.vstack([g_pt[None] if goal_ok else np.empty((0, 2)), b.verts[vi], aux_p])
        kinds = np.array([GOAL] * int(goal_ok) + [VERTEX] * len(vi) + [AUX] * len(aux_p))
        ok, chi, leg = admissible(p, s.course, pts, cfg, to_goal=kinds == GOAL, from_start=s.kind == START)
        pts, chi, leg, kinds = pts[ok], chi[ok], leg[ok], kinds[ok]
        times = s.t + leg / v
        h = self._heuristic(fs, g_pt, pts, times, kinds)
        for k in range(len(pts)):
            yield (
                State((float(pts[k, 0]), float(pts[k, 1])), float(times[k]), float(chi[k]), str(kinds[k])),
                float(leg[k] / v),
                float(h[k]),
            )

    def _heuristic(self, fs: FreeSpace, g_pt, pts, times, kinds) -> np.ndarray:
        if self.cfg.heuristic == "dijkstra" or not len(pts):
            return np.zeros(len(pts))
        euclid = edh(pts, times, self.goal, self.cfg.tas_mps, self.availability)
        if self.cfg.heuristic == "edh":
            return euclid
        static = self._static_paths(fs, g_pt).from_points(pts) / self.cfg.tas_mps
        return np.where(np.isfinite(static), np.maximum(static, euclid), euclid)

    def _static_paths(self, fs: FreeSpace, g_pt: np.ndarray) -> StaticPaths:
        """SSPH graph of the start state's free space for the whole search (one reduced
        visibility graph per replan instead of one per expansion), to the goal's interception
        point from the start (a moving goal, or a fixed one seen from the air-mass frame)."""
        if self.static is None:
            self.static = StaticPaths(fs, g_pt)
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
) -> Trajectory:
    """Near-time-optimal, time-monotone, flyable trajectory from (p0, t0, course0) to the goal
    (or a partial one, see Trajectory, lasting at least ``min_partial_s`` [s])."""
    wall = time.perf_counter()
    p0 = np.asarray(p0, float)
    ends = goal.at(np.array([t0, t0 + cfg.horizon_s]))
    w = workspace if workspace is not None else default_workspace(np.vstack([p0, ends]), cfg, cfg.mission_area)
    exp = _Expander(tl, goal, cfg, w, turning or cfg.turning)
    q_p, q_t, q_c = 0.01 * cfg.leg_m, 0.01 * cfg.dt_s, math.radians(1.0)

    def key(s: State):
        return round(s.p[0] / q_p), round(s.p[1] / q_p), round(s.t / q_t), round(s.course / q_c) % 360, s.kind == GOAL

    start = State((float(p0[0]), float(p0[1])), float(t0), float(course0), START)
    res = astar(
        start, exp, lambda s: s.kind == GOAL, key, cfg.max_expansions, partial_ok=lambda s: s.t >= t0 + min_partial_s
    )
    path = res.path if res.status == "ok" else res.partial
    return Trajectory(
        np.array([s.p for s in path]).reshape(-1, 2),
        np.array([s.t for s in path]),
        np.array([s.course for s in path]),
        np.array([s.kind for s in path]),
        res.status,
        res.expanded,
        time.perf_counter() - wall,
        exp.start_space,
    )
