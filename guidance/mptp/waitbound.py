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
from shapely.geometry import Polygon
from shapely.geometry.base import BaseGeometry

from guidance.mptp.goal import GoalTrack
from guidance.mptp.timeline import ObstacleTimeline

NEAR_M = 1e-6  # grid points this close to the boundary go to GEOS [m]
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
        fixed = None if goal.moving else np.maximum(np.hypot(*_offsets(xs, ys, goal.points[0])) - r, 0.0)
        b = np.empty((len(t_k), nx, ny))
        for i in range(len(t_k) - 1, -1, -1):
            near = fixed if fixed is not None else np.maximum(np.hypot(*_offsets(xs, ys, goal.at(t_k[i]))) - r, 0.0)
            direct = t_k[i] + near / (speed + v_goal)
            if i < len(t_k) - 1:  # max(direct, min(direct if possible, nxt)) without the min
                nxt = disc_minimum(b[i + 1], disc)
                direct = np.where(direct < t_k[i] + tau, direct, np.maximum(direct, nxt))
            b[i] = np.where(blocked[i // substeps], np.inf, direct)
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


def _offsets(xs: np.ndarray, ys: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Grid offsets from point g, (len(xs), 1) and (1, len(ys)) (broadcast to the grid)."""
    return (xs - g[0])[:, None], (ys - g[1])[None, :]


def disc_minimum(a: np.ndarray, disc: np.ndarray) -> np.ndarray:
    """scipy.ndimage.minimum_filter(a, footprint=disc, mode="constant", cval=inf), for a
    footprint (2k+1, 2k+1) symmetric about its centre whose rows are centred runs (a disc):
    per row offset, the minimum over that row's run of a column-wise running minimum (the
    same elements, so the same values, in a few whole-array numpy minimums)."""
    k = disc.shape[0] // 2
    nx, ny = a.shape
    p = np.pad(a, k, constant_values=np.inf)
    half = disc.sum(axis=1) // 2  # half run per row offset; rows without one (0 cells) are skipped
    runs = [p[:, k : k + ny]]  # runs[w][:, j]: min of p's columns k + j - w .. k + j + w
    for w in range(1, int(half.max()) + 1):
        runs.append(np.minimum(runs[-1], np.minimum(p[:, k - w : k - w + ny], p[:, k + w : k + w + ny])))
    out = np.full(a.shape, np.inf)
    for d in range(2 * k + 1):
        if disc[d].any():
            np.minimum(out, runs[int(half[d])][d : d + nx], out=out)
    return out


def _inside(geom: BaseGeometry, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """(len(xs), len(ys)) bool: grid point (xs[i], ys[j]) strictly inside ``geom`` (a (Multi)Polygon),
    what shapely.contains_xy gives, by crossing parity along each grid column: a point is
    inside when an odd number of boundary edges cross its column below it. Points within
    NEAR_M of a crossing and columns within NEAR_M of a vertex (where rounding or a vertical
    edge could decide) are tested with contains_xy."""
    if geom.is_empty:
        return np.zeros((len(xs), len(ys)), bool)
    coords, ring = shapely.get_coordinates(shapely.get_rings(shapely.get_parts(geom)), return_index=True)
    same = ring[1:] == ring[:-1]  # consecutive points of one ring (closed rings: every edge)
    a, b = coords[:-1][same], coords[1:][same]
    lo, hi = np.minimum(a[:, 0], b[:, 0]), np.maximum(a[:, 0], b[:, 0])
    first, stop = np.searchsorted(xs, lo, side="left"), np.searchsorted(xs, hi, side="left")  # lo <= x < hi
    n = stop - first
    e = np.repeat(np.arange(len(a)), n)
    ci = first[e] + (np.arange(len(e)) - np.repeat(np.cumsum(n) - n, n))
    yc = a[e, 1] + (xs[ci] - a[e, 0]) * (b[e, 1] - a[e, 1]) / (b[e, 0] - a[e, 0])
    below = np.searchsorted(ys, yc, side="right")  # ys[j] > yc for j >= below
    count = np.zeros((len(xs), len(ys) + 1), int)
    np.add.at(count, (ci, below), 1)
    out = np.cumsum(count, axis=1)[:, :-1] % 2 == 1
    unsure = np.zeros(out.shape, bool)
    for j in (below - 1, below):
        ok = (j >= 0) & (j < len(ys))
        unsure[ci[ok], j[ok]] |= np.abs(ys[j[ok]] - yc[ok]) <= NEAR_M
    vx = np.searchsorted(xs, coords[:, 0])
    for i in (vx - 1, vx):
        ok = (i >= 0) & (i < len(xs))
        unsure[i[ok][np.abs(xs[i[ok]] - coords[ok, 0]) <= NEAR_M]] = True
    ui, uj = np.nonzero(unsure)
    out[ui, uj] = shapely.contains_xy(geom, xs[ui], ys[uj])
    return out
