"""Reach-set performance notions and size bounds (spec §4.1/§4.2, eqs. 6.69-6.86): tree sizes,
bounds, footprints, coverage sets and ratios, and the turning a cell needs (the smoothness bound).
Footprints are ordered tuples of flat cell indices of the grid (LCF, docs/reachset.md)."""

from __future__ import annotations

import numpy as np

from avoidance.reachset.config import ExpansionConfig, GridConfig, ReachSetConfig
from avoidance.reachset.grid import AvoidanceGrid
from avoidance.reachset.movement import N_MOVEMENTS, PrimitiveTable
from avoidance.reachset.tree import ReachSetTree, expand


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


def _footprint(parent_fp: tuple[int, ...], cells: np.ndarray) -> tuple[int, ...]:
    """(6.70): the parent's ordered passing cells extended by ``cells`` (a cell continued from the
    parent's tip counts once)."""
    fp = list(parent_fp)
    for c in cells.tolist():
        if not fp or fp[-1] != c:
            fp.append(c)
    return tuple(fp)


def leaf_footprints(tree: ReachSetTree) -> set[tuple[int, ...]]:
    """Coverage set (def. 16, 6.72) of a reach set: the distinct footprints of its trajectories
    (root-to-leaf paths), each an ordered tuple of flat cell indices."""
    fps: list[tuple[int, ...]] = [()] * tree.n_nodes
    for n in range(1, tree.n_nodes):
        fps[n] = _footprint(fps[tree.parent[n]], tree.cells[tree.cells_ptr[n] : tree.cells_ptr[n + 1]])
    return {fps[leaf] for leaf in tree.leaves()}


def full_coverage_set(grid: AvoidanceGrid, table: PrimitiveTable) -> set[tuple[int, ...]]:
    """Coverage set of the full contained reach set, the reference of (6.73): every movement
    sequence whose samples all stay in ``grid``, followed until its tip enters the last layer
    (the trajectories a pruned reach set keeps). Cost grows as 9^layers: a 5-layer grid only
    (spec A-34: 66 430 nodes)."""
    pos, att = np.zeros((1, 3)), np.zeros((1, 3))
    fps: list[tuple[int, ...]] = [()]
    out: set[tuple[int, ...]] = set()
    last = grid.cfg.n_layers - 1
    while len(fps):
        par = np.repeat(np.arange(len(fps)), N_MOVEMENTS)
        mov = np.tile(np.arange(N_MOVEMENTS), len(fps))
        samples, att_end, cells = expand(table, grid, pos[par], att[par], mov)
        ok = np.flatnonzero(np.all(cells >= 0, axis=1))
        new = [_footprint(fps[par[r]], cells[r]) for r in ok]
        final = grid.layer[cells[ok, -1]] == last
        out.update(f for f, x in zip(new, final, strict=True) if x)
        go = ok[~final]
        fps = [f for f, x in zip(new, final, strict=True) if not x]
        pos, att = samples[go, -1], att_end[go]
    return out


def coverage_ratio(reduced: set[tuple[int, ...]], reference: set[tuple[int, ...]]) -> float:
    """(6.73): share of the reference coverage set the reduced one holds."""
    return len(reduced & reference) / len(reference)


def min_turns_to_cells(grid: AvoidanceGrid, table: PrimitiveTable) -> np.ndarray:
    """(n_cells,) lower bound on the non-Straight movements of any trajectory whose tip lies in
    each cell: a point's azimuth (elevation) from the grid origin is a mean of the headings
    (pitches) flown to it, so reaching a cell whose nearest edge is at angle a needs a heading
    of at least a, i.e. ceil(a / increment) turns; a diagonal movement turns both axes at once."""
    inc = table.d_att.max(axis=0)
    need = []
    for axis, step in ((1, inc[2]), (2, inc[1])):
        edge = np.maximum(np.maximum(grid.lower[:, axis], -grid.upper[:, axis]), 0.0)
        need.append(np.ceil(edge / step - 1e-9))
    return np.maximum(*need)
