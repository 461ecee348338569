"""Map obstacles (spec §5.2, (6.100)-(6.108), A-13, A-22).

A map obstacle is a body (footprint prism or ball) plus a safety-margin shell. Instead of a
homogeneous Cartesian cloud, each cell carries a fixed polar lattice of volume samples
(``AvoidanceGrid.volume_samples``) whose weights are the volumes they stand for; a sample inside
the body or its margin contributes ``weight / threshold_volume`` (6.105), so
``map(cell, obstacle) = min(volume of the cell inside the obstacle / threshold_volume, 1)`` (6.107
with min) and ``map(cell) = max`` over the active obstacles (6.108). Every cell is sampled,
including the small first-layer cells.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from avoidance.reachset.config import MapConfig
from avoidance.reachset.frames import GridPose, ne_to_gcf_xy
from avoidance.reachset.grid import AvoidanceGrid
from sim.core.threats import PrismObstacle, SphereThreat


@dataclass(frozen=True, slots=True)
class MapObstacle:
    """A body in the z-up GCF: ``footprint`` (GCF x = east, y = north) extruded over
    ``z_band`` [m], or a ball (``footprint`` = its centre point, ``radius`` > 0); ``margin`` [m]."""

    footprint: BaseGeometry
    z_band: tuple[float, float]
    margin: float
    radius: float = 0.0

    @staticmethod
    def from_prism(p: PrismObstacle, margin: float) -> MapObstacle:
        return MapObstacle(shapely.transform(p.footprint, ne_to_gcf_xy), (p.up_min_m, p.up_max_m), margin)

    @staticmethod
    def from_sphere(s: SphereThreat, margin: float) -> MapObstacle:
        c = np.asarray(s.center_ned, float)
        return MapObstacle(shapely.Point(c[1], c[0]), (-c[2], -c[2]), margin, s.radius_m)

    def inside(self, p: np.ndarray) -> np.ndarray:
        """Samples (M, 3) GCF inside body or margin."""
        r = self.radius + self.margin
        if self.radius > 0:
            c = np.array([self.footprint.x, self.footprint.y, self.z_band[0]])
            return np.einsum("ij,ij->i", p - c, p - c) <= r * r
        lo, hi = self.z_band
        ok = (p[:, 2] >= lo - r) & (p[:, 2] <= hi + r)
        x0, y0, x1, y1 = self.footprint.bounds
        ok &= (p[:, 0] >= x0 - r) & (p[:, 0] <= x1 + r) & (p[:, 1] >= y0 - r) & (p[:, 1] <= y1 + r)
        idx = np.flatnonzero(ok)
        shape = self.footprint.buffer(r) if r > 0 else self.footprint
        ok[idx] = shapely.contains_xy(shape, p[idx, 0], p[idx, 1])
        return ok

    def distance_xy(self, xy: np.ndarray) -> float:
        """Horizontal distance from a GCF point to the body [m]."""
        return max(float(shapely.distance(self.footprint, shapely.Point(*xy))) - self.radius, 0.0)


def map_rating(grid: AvoidanceGrid, pose: GridPose, obstacles: list[MapObstacle], cfg: MapConfig) -> np.ndarray:
    """(n_cells,) map rating of the active obstacles (selection (6.101) with ``≥``)."""
    out = np.zeros(grid.n_cells)
    active = [o for o in obstacles if o.distance_xy(pose.origin[:2]) - o.margin <= grid.range]
    if not active:
        return out
    pts, cells, w = grid.volume_samples
    gcf = pose.to_gcf(pts)
    for o in active:
        inside = o.inside(gcf)
        rating = np.bincount(cells[inside], weights=w[inside], minlength=grid.n_cells) / cfg.threshold_volume
        np.maximum(out, np.minimum(rating, 1.0), out=out)
    return out
