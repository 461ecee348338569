"""Cost-to-go to the goal around the known static constraints (decision D-17 of docs/reachset.md).

Alg. 6.6 ranks the reachable (outer) cells by their straight distance to the goal. A dead end
larger than the grid then pulls the vehicle in for ever: the pocket of a PentaTrap that opens
towards it (S5: it circled in the pocket), a maze whose corridor to the goal starts away from it
(S3: it held north towards a wall until the 19 m turn radius could no longer make the corridor
east, squeezed out between two buildings in a relaxed run and circled the maze outside). The
obstacles known before the flight (keep-out geofences, grown by their safety margin) give a
better measure: the shortest distance around them to the goal, on a raster (8-connected
Dijkstra from the goal). Where no route exists, or for points inside a grown body, the value of
the nearest routed raster point plus the gap, so the measure is finite everywhere.

Frames: z-up GCF [m] (x east, y north); values [m].
"""

from __future__ import annotations

import numpy as np
import shapely
from scipy.ndimage import distance_transform_edt, map_coordinates
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra
from shapely.geometry import Polygon


class CostToGo:
    """Shortest distance [m] to ``goal`` (GCF, its x-y) around ``bodies`` (GCF x-y polygons, the
    margin already added), on a raster of ``spacing`` [m] covering the goal, ``around`` (GCF x-y
    points, e.g. the vehicle) and the bodies, widened by ``pad`` [m]. Outside the raster: the
    value at the nearest raster point plus the distance to it."""

    _STEPS = ((1, 0, 1.0), (0, 1, 1.0), (1, 1, np.sqrt(2.0)), (1, -1, np.sqrt(2.0)))

    def __init__(self, goal: np.ndarray, bodies: list[Polygon], spacing: float, pad: float, around: np.ndarray):
        goal = np.asarray(goal, float)[:2]
        pts = [goal[None], np.asarray(around, float).reshape(-1, 2)] + [np.reshape(b.bounds, (2, 2)) for b in bodies]
        lo = np.min(np.vstack(pts), axis=0) - pad
        hi = np.max(np.vstack(pts), axis=0) + pad
        self.lo, self.spacing = lo, float(spacing)
        shape = tuple(int(n) for n in np.ceil((hi - lo) / spacing).astype(int) + 1)
        x, y = np.meshgrid(lo[0] + spacing * np.arange(shape[0]), lo[1] + spacing * np.arange(shape[1]), indexing="ij")
        blocked = np.zeros(shape, bool)
        for b in bodies:
            blocked |= shapely.contains_xy(b, x, y)
        g = tuple(np.clip(np.rint((goal - lo) / spacing).astype(int), 0, np.array(shape) - 1))
        blocked[g] = False
        dist = self._dijkstra(~blocked, int(np.ravel_multi_index(g, shape)), spacing).reshape(shape)
        unrouted = ~np.isfinite(dist)
        if unrouted.any():
            gap, (ix, iy) = distance_transform_edt(unrouted, return_indices=True)
            dist = dist[ix, iy] + spacing * gap
        self.values = dist

    def _dijkstra(self, free: np.ndarray, source: int, spacing: float) -> np.ndarray:
        idx = np.arange(free.size).reshape(free.shape)
        rows, cols, w = [], [], []
        nx, ny = free.shape
        for dx, dy, length in self._STEPS:
            a = (slice(0, nx - dx), slice(max(-dy, 0), ny - max(dy, 0)))
            b = (slice(dx, nx), slice(max(dy, 0), ny - max(-dy, 0)))
            ok = free[a] & free[b]
            rows.append(idx[a][ok])
            cols.append(idx[b][ok])
            w.append(np.full(int(ok.sum()), spacing * length))
        graph = coo_matrix(
            (np.concatenate(w), (np.concatenate(rows), np.concatenate(cols))), shape=(free.size, free.size)
        )
        return dijkstra(graph.tocsr(), directed=False, indices=source)

    def __call__(self, xy: np.ndarray) -> np.ndarray:
        """Cost-to-go [m] of GCF points (..., >= 2) (their x-y), bilinear between raster points."""
        p = np.asarray(xy, float)[..., :2]
        top = self.lo + self.spacing * (np.array(self.values.shape) - 1)
        inside = np.clip(p, self.lo, top)
        rel = ((inside - self.lo) / self.spacing).reshape(-1, 2).T
        v = map_coordinates(self.values, rel, order=1, mode="nearest").reshape(p.shape[:-1])
        return v + np.linalg.norm(p - inside, axis=-1)
