"""Reach-set performance notions and size bounds (spec §4.1/§4.2, eqs. 6.69-6.86)."""

from __future__ import annotations

import numpy as np

from avoidance.reachset.config import ExpansionConfig, GridConfig, ReachSetConfig
from avoidance.reachset.movement import N_MOVEMENTS
from avoidance.reachset.tree import ReachSetTree


def full_tree_size(n_movements: int, n_layers: int) -> int:
    """(6.69): nodes of the full tree, 1 + Σ M^i."""
    return 1 + sum(n_movements**i for i in range(1, n_layers + 1))


def expansion_bounds(part: ExpansionConfig, grid: GridConfig) -> tuple[float, float]:
    """(trajectories, nodes) upper bounds of one expansion constraint (6.77/6.78, 6.81/6.82);
    infinite for an unlimited spread or the ACAS-like set (no bound in [T])."""
    cells_per_layer = grid.n_h * grid.n_v  # layerCellCount
    if part.spread_limit is None or part.method == "acas":
        return np.inf, np.inf
    trajectories = cells_per_layer * part.spread_limit * N_MOVEMENTS
    per_cell = N_MOVEMENTS * part.spread_limit if part.method == "chaotic" else part.spread_limit
    return trajectories, grid.n_layers * cells_per_layer * per_cell


def bounds(cfg: ReachSetConfig, grid: GridConfig) -> tuple[float, float]:
    """Bounds of a (combined) reach set: sums over its parts (6.85/6.86)."""
    b = np.array([expansion_bounds(p, grid) for p in cfg.parts])
    return float(b[:, 0].sum()), float(b[:, 1].sum())


def trajectory_count(tree: ReachSetTree) -> int:
    """Trajectories = root-to-leaf paths."""
    return len(tree.leaves())
