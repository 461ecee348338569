"""Cost-to-go estimates H [s] for the time-dependent A* (seed 002, 4.3).

- Dijkstra: H = 0.
- EDH: the time to fly straight to the goal (to the interception point of a moving goal), or
  longer, to the first planning interval at or after that arrival in which the goal is not
  covered by the obstacle envelope (:class:`GoalAvailability`): an arrival inside a covered
  interval ends inside EX_obs, so it cannot happen and the bound stays admissible. Without this
  wait term a covered goal makes A* expand every state that is closer than the wait.
- SSPH (:class:`StaticPaths`): the shortest static path to the goal in a free estimated state
  space, over its reduced visibility graph (a Dijkstra from the goal), divided by V; the search
  (search.py) builds it once per replan (the thesis: on EX_free(x_in) per expansion). Where the
  goal is not connected to a state in that static view (the goal is covered now but uncovers
  later, 5.4) the thesis notes SSPH has no value; we then fall back to EDH for that state
  instead of penalising edges.

Admissibility with waiting and wind (the search may hold anywhere, and plans in the air-mass
frame where the aircraft flies at exactly V and a ground goal drifts at minus the wind):
- EDH: no path reaches the goal before the straight-line interception at V, and a later start
  (a wait) only moves that time later; the availability term only skips times at which the
  goal is inside the envelope. Both terms are monotone in the state's time, so EDH stays
  consistent along every edge, holds included.
- SSPH: the static view must not contain an obstacle that a wait would see move away, so it is
  built on the start's *permanent* obstacle (statespace.obstacle_region, ``permanent``): each
  point of it is inside the envelope at every time it can be reached. A flown path avoids it,
  so its length is at least the static distance d_s(p, g) to wherever the goal is on arrival.
  A moving goal (a goal track, or any ground goal in wind) is met at some tau >= tau0, the
  earliest interception from the start; while its track stays in the static free space from
  tau0 to T_w, d_s(g(tau0), g(tau)) <= v_g (tau - tau0) (v_g its largest speed), so
  V (tau - t) >= d_s(p, g(tau0)) - v_g (tau - tau0), i.e. tau >= (d_s + V t + v_g tau0) / (V + v_g);
  capped at T_w (an arrival after T_w is later than the cap anyway). When the track leaves the
  static free space the SSPH is not used (EDH only).
- The search takes max(EDH, SSPH); the maximum of admissible bounds is admissible.
"""

from __future__ import annotations

import numpy as np
import shapely
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from guidance.mptp.goal import GoalTrack
from guidance.mptp.statespace import FreeSpace
from guidance.mptp.timeline import ObstacleTimeline
from guidance.mptp.visibility import blocked, reduced_graph, visible_vertices


class GoalAvailability:
    """Whether the goal can be reached in each planning interval of ``tl``: not when it lies
    inside the interval's obstacle envelope (a fixed goal: its point; a moving goal: its track
    over the interval). Intervals are tested lazily and cached."""

    def __init__(self, tl: ObstacleTimeline, goal: GoalTrack):
        self.tl, self.goal = tl, goal
        self._covered: dict[int, bool] = {}

    def covered(self, j: int) -> bool:
        if j not in self._covered:
            t0, t1 = self.tl.level_time(j), self.tl.level_time(j + 1)
            knots = self.goal.times[(self.goal.times > t0) & (self.goal.times < t1)]
            pts = self.goal.at(np.concatenate([[t0], knots, [t1]]))
            track = shapely.points(pts[0]) if not self.goal.moving else shapely.linestrings(pts)
            self._covered[j] = bool(shapely.contains(self.tl.envelope(j), track))
        return self._covered[j]

    def earliest(self, t: np.ndarray) -> np.ndarray:
        """Earliest time(s) >= t [s] in an interval where the goal is not covered (inf when it
        stays covered to the end of the timeline, whose last level is held)."""
        t = np.asarray(t, float)
        out = t.copy()
        n = self.tl.n_levels
        for i, j in enumerate(self.tl.interval(t)):
            if not np.isfinite(t[i]):
                continue
            k = int(j)
            while k < n and self.covered(k):
                k += 1
            out[i] = t[i] if k == j else (self.tl.level_time(k) if k < n else np.inf)
        return out


def edh(
    points: np.ndarray, times: np.ndarray, goal: GoalTrack, speed: float, availability: GoalAvailability | None = None
) -> np.ndarray:
    """Time [s] to the goal in a straight line; with ``availability``, at least until the goal
    is first reachable after that arrival."""
    arrival = goal.intercept(points, times, speed)
    if availability is not None:
        arrival = availability.earliest(arrival)
    return arrival - times


class StaticPaths:
    """Shortest static distances [m] to ``goal_pt`` in ``fs`` via its reduced visibility graph."""

    def __init__(self, fs: FreeSpace, goal_pt: np.ndarray):
        b = fs.boundary
        self.fs, self.goal = fs, np.asarray(goal_pt, float).reshape(2)
        n = len(b.verts)
        i, j, w = reduced_graph(b)
        _gi, gv = visible_vertices(self.goal[None], b)
        rows = np.concatenate([i, j, np.full(len(gv), n), gv])
        cols = np.concatenate([j, i, gv, np.full(len(gv), n)])
        wg = np.linalg.norm(b.verts[gv] - self.goal, axis=1)
        wts = np.concatenate([w, w, wg, wg])
        graph = coo_matrix((np.maximum(wts, 1e-9), (rows, cols)), shape=(n + 1, n + 1)).tocsr()
        self.dist = dijkstra(graph, directed=False, indices=n)[:n]
        self.n_edges = len(i) + len(gv)

    def from_points(self, pts: np.ndarray) -> np.ndarray:
        """Static shortest distance [m] from arbitrary points (inf when not connected)."""
        b = self.fs.boundary
        out = np.full(len(pts), np.inf)
        direct = ~blocked(pts, np.repeat(self.goal[None], len(pts), 0), b)
        out[direct] = np.linalg.norm(pts[direct] - self.goal, axis=1)
        si, vi = visible_vertices(pts, b)
        if len(si):
            via = np.linalg.norm(b.verts[vi] - pts[si], axis=1) + self.dist[vi]
            np.minimum.at(out, si, via)
        return out


class StaticBound:
    """SSPH arrival bound [s] for a goal that may move (see the module notes): static distances
    in ``fs`` (a permanent obstacle view) to the goal at ``tau0`` [s], its track checked in the
    static free space up to ``t_w`` [s]; ``usable`` False when the track leaves it."""

    def __init__(self, fs: FreeSpace, goal: GoalTrack, tau0: float, t_w: float, speed: float):
        self.paths = StaticPaths(fs, goal.at(tau0))
        self.tau0, self.t_w, self.speed = tau0, max(t_w, tau0), speed
        inner = goal.times[(goal.times > self.tau0) & (goal.times < self.t_w)]
        knots = np.concatenate([[self.tau0], inner, [self.t_w]])
        track = goal.at(knots)
        legs = np.linalg.norm(np.diff(track, axis=0), axis=1)
        self.v_goal = float((legs / np.maximum(np.diff(knots), 1e-9)).max()) if len(legs) else 0.0
        moving = legs > 1e-6
        self.usable = self.v_goal == 0.0 or not blocked(track[:-1][moving], track[1:][moving], fs.boundary).any()

    def arrival(self, pts: np.ndarray, times: np.ndarray) -> np.ndarray:
        """Lower bounds on the arrival time [s] from points (N, 2) at times (N,) (inf where the
        static view does not connect them to the goal, or the bound is unusable)."""
        if not self.usable:
            return np.full(len(pts), np.inf)
        d = self.paths.from_points(pts)
        v, vg = self.speed, self.v_goal
        tau = (d + v * times + vg * self.tau0) / (v + vg)
        return tau if vg == 0.0 else np.minimum(tau, np.where(np.isfinite(d), self.t_w, np.inf))
