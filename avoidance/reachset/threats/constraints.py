"""Static and moving constraints: geofences, airspace, weather (spec §5.3/§5.5, A-15, A-28).

A constraint is a horizontal body (polygon, GCF x = east, y = north) over an altitude band, with
a safety-margin ring: a cell is *hard* if its horizontal footprint touches the body and the
altitude bands overlap, *soft* if it is within the margin but not hard. ``mode = "circle"``
replaces the body by its minimal enclosing circle (the thesis' barrel, Welzl); ``"polygon"`` is
exact. A keep-in fence is hard wherever a cell leaves it and soft within the margin inside.
Moving constraints are tested at the time the UAS leaves each cell: the footprint is shifted back
by ``velocity · Δt``, Δt = t_grid + UAS_leave(cell) − detection time (equivalent to moving the body).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import shapely
from shapely.geometry import Polygon

from avoidance.reachset.config import ConstraintConfig
from avoidance.reachset.frames import GridPose, ne_to_gcf_xy
from avoidance.reachset.grid import AvoidanceGrid
from sim.core.threats import Geofence, StormSnapshot


@dataclass(frozen=True, slots=True)
class Constraint:
    """Record (6.109)/(6.152) in the z-up GCF: ``body`` polygon [m], ``z_band`` heights [m],
    ``margin`` [m], horizontal ``velocity`` [m/s] at ``detection_time`` [s], ``keep_in``."""

    body: Polygon
    z_band: tuple[float, float]
    margin: float
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(2))
    detection_time: float = 0.0
    keep_in: bool = False

    @property
    def moving(self) -> bool:
        return bool(np.any(self.velocity != 0.0))


def from_geofence(g: Geofence, margin: float) -> Constraint:
    return Constraint(shapely.transform(g.area, ne_to_gcf_xy), (g.up_min_m, g.up_max_m), margin, keep_in=g.keep_in)


def from_storm(s: StormSnapshot, margin: float) -> list[Constraint]:
    """Storm cells as moving constraints between each cell's base and top (heights above the
    origin [m]; unbounded where the nowcast gives none)."""
    vel = np.zeros((len(s.cells), 2)) if s.velocities_ne is None else ne_to_gcf_xy(np.asarray(s.velocities_ne, float))
    return [
        Constraint(shapely.transform(c, ne_to_gcf_xy), (float(e[0]), float(e[1])), margin, v, s.t)
        for c, v, e in zip(s.cells, vel, s.extents(), strict=False)
    ]


def _footprints_gcf(
    grid: AvoidanceGrid, pose: GridPose, c: Constraint, t_grid: float, uas_leave: np.ndarray
) -> np.ndarray:
    """Cell footprints expressed in GCF, shifted back by the constraint's motion per cell."""
    coords, idx = shapely.get_coordinates(grid.footprints, return_index=True)
    xy = coords @ pose.rot[:2, :2].T + pose.origin[:2]
    if c.moving:
        xy = xy - np.outer(t_grid + uas_leave - c.detection_time, c.velocity)[idx]
    return shapely.set_coordinates(grid.footprints.copy(), xy)


def classify(
    grid: AvoidanceGrid,
    pose: GridPose,
    constraints: list[Constraint],
    cfg: ConstraintConfig,
    t_grid: float,
    uas_leave: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """(hard, soft) boolean masks (n_cells,) over the active constraints (6.110, 6.113-6.115)."""
    hard = np.zeros(grid.n_cells, bool)
    soft = np.zeros(grid.n_cells, bool)
    z = pose.origin[2] + grid.z_band
    origin = shapely.Point(*pose.origin[:2])
    horizon = float(uas_leave.max(initial=0.0))
    for c in constraints:
        reach = (
            grid.range + c.margin + 2.0 * float(np.linalg.norm(c.velocity)) * (horizon + abs(t_grid - c.detection_time))
        )
        fp = _footprints_gcf(grid, pose, c, t_grid, uas_leave)
        lo, hi = c.z_band
        if c.keep_in:
            if (
                shapely.distance(c.body.exterior, origin) > reach
                and c.body.contains(origin)
                and lo + c.margin <= z.min()
                and z.max() <= hi - c.margin
            ):
                continue
            out_alt = (z[:, 0] < lo) | (z[:, 1] > hi)
            near_alt = (z[:, 0] < lo + c.margin) | (z[:, 1] > hi - c.margin)
            h = ~shapely.within(fp, c.body) | out_alt
            s = shapely.dwithin(fp, c.body.exterior, c.margin) | near_alt
        else:
            if shapely.distance(c.body, origin) > reach or hi < z.min() or lo > z.max():
                continue
            overlap = (z[:, 1] >= lo) & (z[:, 0] <= hi)
            if cfg.mode == "circle":
                circle = shapely.minimum_bounding_circle(c.body)
                centre, radius = circle.centroid, shapely.minimum_bounding_radius(c.body)
                h = shapely.dwithin(fp, centre, radius) & overlap
                s = shapely.dwithin(fp, centre, radius + c.margin) & overlap
            else:
                h = shapely.intersects(fp, c.body) & overlap
                s = shapely.dwithin(fp, c.body, c.margin) & overlap
        hard |= h
        soft |= s & ~h
    return hard, soft & ~hard
