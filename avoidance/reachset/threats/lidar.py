"""LiDAR-detected obstacles and visibility (spec §5.1, (6.89)-(6.99), A-11, A-21).

A ray belongs to the grid column (j, k) of its direction seen from the grid origin; a hit belongs
to the cell containing its return point. Per cell: ``h = hits / rays(column)``, obstacle rating
``min(h · Area(r̄) / threshold_area, 1)`` (surface, range-invariant), visibility = share of the
column's rays still travelling at the start of the cell's layer: not stopped by a return before
it, and not ended at the sensor's range before it (a cell beyond the range is not seen, so the
map keeps its weight there, (6.158)). Columns without rays are not visible (0).
"""

from __future__ import annotations

import numpy as np

from avoidance.reachset.config import LidarConfig
from avoidance.reachset.frames import GridPose, to_polar
from avoidance.reachset.grid import AvoidanceGrid
from sim.core.threats import LidarScan


def column_of(grid: AvoidanceGrid, theta_phi: np.ndarray) -> np.ndarray:
    """Column index ``j·K + k`` (= the layer-1 cell) of directions (N, 2) [rad], -1 outside."""
    d = np.full((len(theta_phi), 1), grid.starts[0] + 0.5 * grid.steps[0])
    return grid.cell_index_polar(np.hstack([d, theta_phi]))


def lidar_ratings_polar(
    grid: AvoidanceGrid, ray_dirs: np.ndarray, hits: np.ndarray, cfg: LidarConfig, ray_reach: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Obstacle rating and visibility per cell from ray directions (R, 2) = (θ, φ) and hit points
    (H, 3) = (d, θ, φ) in the grid's polar frame. ``ray_reach`` (R,) [m]: how far each ray saw
    without a return (its end at the sensor's range; inf for rays that hit, their hindrance
    counts instead); a cell beyond it is not seen by that ray. None: every ray sees the whole grid."""
    n_col = grid.shape[1] * grid.shape[2]
    col = column_of(grid, ray_dirs)
    rays = np.bincount(col[col >= 0], minlength=n_col).astype(float)
    cell = grid.cell_index_polar(hits) if len(hits) else np.zeros(0, np.int64)
    ok = cell >= 0
    n_hits = np.bincount(cell[ok], minlength=grid.n_cells).astype(float)
    r_sum = np.bincount(cell[ok], weights=hits[ok, 0], minlength=grid.n_cells)
    rays_cell = np.tile(rays, grid.shape[0])
    with np.errstate(invalid="ignore", divide="ignore"):
        h = np.where(rays_cell > 0, n_hits / rays_cell, 0.0)
        r_mean = np.where(n_hits > 0, r_sum / n_hits, 0.0)
    obstacle = np.minimum(h * grid.face_area(r_mean, np.arange(grid.n_cells)) / cfg.threshold_area, 1.0)
    h3 = grid.per_cell(h)
    travelled = np.cumsum(h3, axis=0) - h3  # hindrance of the layers before each cell (6.98)
    visibility = np.clip(1.0 - travelled - _ended(grid, col, ray_reach, rays), 0.0, 1.0).reshape(-1)
    return obstacle, np.where(rays_cell > 0, visibility, 0.0)


def _ended(grid: AvoidanceGrid, col: np.ndarray, ray_reach: np.ndarray | None, rays: np.ndarray) -> np.ndarray | float:
    """Share of each column's rays that ended without a return before each layer, (I, J, K)."""
    if ray_reach is None:
        return 0.0
    n_layers, n_col = grid.shape[0], len(rays)
    reach = np.asarray(ray_reach, float)
    ok = col >= 0
    seen = np.ceil(np.clip((reach[ok] - grid.starts[0]) / grid.steps[0] - grid.cfg.eps, 0.0, n_layers)).astype(np.int64)
    counts = np.bincount(col[ok] * (n_layers + 1) + seen, minlength=n_col * (n_layers + 1)).reshape(n_col, n_layers + 1)
    ended = np.cumsum(counts, axis=1)[:, :n_layers]  # rays that saw at most i layers, i = 0..I-1
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(rays[:, None] > 0, ended / np.maximum(rays, 1.0)[:, None], 0.0)
    return grid.per_cell(share.T.reshape(-1))


def lidar_ratings(
    grid: AvoidanceGrid, pose: GridPose, scan: LidarScan, cfg: LidarConfig
) -> tuple[np.ndarray, np.ndarray]:
    """Ratings of a project LiDAR scan (NED) in a grid placed at ``pose``. The scan may be taken
    at another position than the grid origin (spec §1.2: scan at t_i, grid at t_{i+1}): every ray
    is re-expressed by its end point (return, or the end of the range) seen from the grid origin."""
    hit = np.asarray(scan.hit, bool)
    ends = scan.origin_ned + scan.directions_ned * np.where(hit, scan.ranges_m, scan.max_range_m)[:, None]
    dtp = to_polar(pose.ned_to_lcf(ends))
    return lidar_ratings_polar(grid, dtp[:, 1:], dtp[hit], cfg, np.where(hit, np.inf, dtp[:, 0]))
