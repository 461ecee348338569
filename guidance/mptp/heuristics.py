"""Cost-to-go estimates H [s] for the time-dependent A* (seed 002, 4.3).

- Dijkstra: H = 0.
- EDH: the time to fly straight to the goal (to the interception point of a moving goal).
- SSPH: the shortest static path to the goal in the current free estimated state space
  EX_free(x_in), over its reduced visibility graph (a Dijkstra from the goal, run once per
  expansion), divided by V. Where the goal is not connected to a state in that static view (the
  goal is covered now but uncovers later, 5.4) the thesis notes SSPH has no value; we then fall
  back to EDH for that state instead of penalising edges.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from guidance.mptp.goal import GoalTrack
from guidance.mptp.statespace import FreeSpace
from guidance.mptp.visibility import blocked, reduced_graph, visible_vertices


def edh(points: np.ndarray, times: np.ndarray, goal: GoalTrack, speed: float) -> np.ndarray:
    return goal.intercept(points, times, speed) - times


class StaticPaths:
    """Shortest static distances [m] to ``goal_pt`` in ``fs`` via its reduced visibility graph."""

    def __init__(self, fs: FreeSpace, goal_pt: np.ndarray):
        b = fs.boundary
        self.fs, self.goal = fs, np.asarray(goal_pt, float)
        n = len(b.verts)
        i, j, w = reduced_graph(b)
        gi, gv = visible_vertices(self.goal[None], b)
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
