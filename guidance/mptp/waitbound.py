"""Wait bound: a lower bound on the arrival time that knows when passages open (the heuristic
term that makes waiting cheap to find).

Frames/units: (north, east) [m] in the planning frame (the air-mass frame in wind), times [s].

Relaxation on time steps T_k = [t_k, t_k + tau) (tau = dt / substeps, inside the timeline's
planning intervals) and square cells of side V tau (half-diagonal r) over the workspace: a
cell is *blocked* in T_k when the disc of radius r around its centre lies inside the envelope
of the planning interval of T_k (then the whole cell does, and the search never puts a state
or a leg point there then). B(c, k) bounds from below the arrival of any path that is in cell c
at some time of T_k:

- it arrives before t_k + tau: no earlier than t_k + (D_k(c) - r)^+ / (V + v_g), where D_k is
  the distance from the cell's centre to the goal at t_k and v_g the goal's largest speed (a
  fixed goal: 0); possible only when that is < t_k + tau;
- or at t_k + tau it is in a cell f not blocked in T_k+1 with |f - c| <= V tau + 2 r (centres),
  and arrives no earlier than B(f, k+1);

so B(c, k) = max(direct, min(direct if possible, min over those f of B(f, k+1))), inf on blocked
cells (the erosion is a little deeper than r: a cell that holds a boundary point is never
blocked); after the last interval (held) B is the direct term. Travel inside an interval is not
checked against obstacles (a relaxation), so the bound is admissible; it is tight where an
obstacle thicker than V dt + 2 r blocks every way for a while (a corridor that opens later).
For a state (p, t): B(cell(p), step(t)) - t (no bound outside the grid).
"""

from __future__ import annotations

import math

import numpy as np
import shapely
from scipy.ndimage import minimum_filter
from shapely.geometry import Polygon
from shapely.geometry.base import BaseGeometry

from guidance.mptp.goal import GoalTrack
from guidance.mptp.timeline import ObstacleTimeline

ERODE_SLACK = 1.0 / math.cos(math.pi / 16)  # the buffer's chords (4 per quarter) stay outside r


class WaitBound:
    """B(c, k) of ``tl`` for ``goal`` over ``workspace`` from ``t0`` to ``t_end`` [s] (later steps
    are left out: the last step's bound is its direct term, a relaxation), at ``speed`` [m/s], on
    time steps of dt / ``substeps`` and cells of side ``speed`` dt / ``substeps`` [m]."""

    def __init__(
        self,
        tl: ObstacleTimeline,
        goal: GoalTrack,
        workspace: Polygon,
        t0: float,
        t_end: float,
        speed: float,
        substeps: int,
    ):
        tau = tl.dt / substeps
        cell = speed * tau
        x0, y0, x1, y1 = workspace.bounds
        self.origin, self.cell, self.tau, self.substeps = np.array([x0, y0]), cell, tau, substeps
        nx, ny = max(1, math.ceil((x1 - x0) / cell)), max(1, math.ceil((y1 - y0) / cell))
        xs, ys = x0 + (np.arange(nx) + 0.5) * cell, y0 + (np.arange(ny) + 0.5) * cell
        r = cell / math.sqrt(2.0)
        self.j0 = int(tl.interval(t0))
        levels = np.arange(self.j0, max(self.j0, int(tl.interval(t_end))) + 1)
        eroded = shapely.buffer(tl.envelopes(levels, levels + 1), -(r * ERODE_SLACK + 1.0), quad_segs=4)
        blocked = np.stack([_inside(e, xs, ys) for e in eroded])
        t_k = tl.level_time(self.j0) + tau * np.arange(len(levels) * substeps)
        knots = goal.times[(goal.times > t_k[0]) & (goal.times < t_k[-1])]
        ktimes = np.concatenate([[t_k[0]], knots, [t_k[-1]]])
        legs = np.linalg.norm(np.diff(goal.at(ktimes), axis=0), axis=1)
        v_goal = float((legs / np.maximum(np.diff(ktimes), 1e-9)).max()) if len(legs) else 0.0
        reach = (speed * tau + 2 * r) / cell
        k = math.floor(reach)
        off = np.arange(-k, k + 1)
        disc = np.hypot(*np.meshgrid(off, off, indexing="ij")) <= reach
        b = np.empty((len(t_k), nx, ny))
        for i in range(len(t_k) - 1, -1, -1):
            g = goal.at(t_k[i])
            dist = np.hypot((xs - g[0])[:, None], (ys - g[1])[None, :])
            direct = t_k[i] + np.maximum(dist - r, 0.0) / (speed + v_goal)
            if i == len(t_k) - 1:
                best = direct
            else:
                nxt = minimum_filter(b[i + 1], footprint=disc, mode="constant", cval=np.inf)
                best = np.minimum(np.where(direct < t_k[i] + tau, direct, np.inf), nxt)
            b[i] = np.where(blocked[i // substeps], np.inf, np.maximum(direct, best))
        self.b, self.t_first = b, float(t_k[0])

    def arrival(self, pts: np.ndarray, times: np.ndarray) -> np.ndarray:
        """Lower bounds on the arrival time [s] from points (N, 2) at times (N,) (-inf outside
        the grid or before its first step; past its last step, the last step's)."""
        ij = np.floor((np.atleast_2d(pts) - self.origin) / self.cell).astype(int)
        k = np.floor((np.asarray(times, float) - self.t_first) / self.tau).astype(int)
        inside = (ij >= 0).all(axis=1) & (ij < self.b.shape[1:]).all(axis=1) & (k >= 0)
        out = np.full(len(ij), -np.inf)
        kk = np.minimum(k[inside], len(self.b) - 1)
        out[inside] = self.b[kk, ij[inside, 0], ij[inside, 1]]
        return out


def _inside(geom: BaseGeometry, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """(len(xs), len(ys)) bool: grid point (xs[i], ys[j]) strictly inside ``geom``, tested only
    within the geometry's bounding box (outside it nothing is inside)."""
    out = np.zeros((len(xs), len(ys)), bool)
    if geom.is_empty:
        return out
    x0, y0, x1, y1 = geom.bounds
    i = slice(*np.searchsorted(xs, [x0, x1], side="left"))
    j = slice(*np.searchsorted(ys, [y0, y1], side="left"))
    gx, gy = np.meshgrid(xs[i], ys[j], indexing="ij")
    out[i, j] = shapely.contains_xy(geom, gx, gy)
    return out
