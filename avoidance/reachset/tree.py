"""Reach-set tree as flat numpy arrays (spec §4.3/§4.10) and its assembly from (parent, movement).

Frame: LCF of a grid placed at the origin with zero attitude (level, X+ forward) [m]; times [s]
from the grid's origin time. Nodes are sorted by depth (node 0 = root, empty buffer), so every
per-decision pass runs level by level with vectorised gathers.

CSR ``node -> passing cells``: for each node, the runs of equal cells its last movement passes
(from the intra-movement samples, spec §2.4/A-26) with the run's entry/leave times. ``cell_new``
marks the runs that extend the footprint (the first run is not new when it continues the parent's
tip cell); reachability counts only those (each footprint cell once).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from avoidance.reachset.grid import AvoidanceGrid
from avoidance.reachset.movement import MovementType, PrimitiveTable, propagate


@dataclass(slots=True)
class ReachSetTree:
    parent: np.ndarray  # (N,) parent node, -1 for the root
    movement: np.ndarray  # (N,) MovementType of the last movement, -1 for the root
    depth: np.ndarray  # (N,) number of movements
    samples: np.ndarray  # (N, n_sub+1, 3) positions along the last movement (sample 0 = parent tip)
    tip_att: np.ndarray  # (N, 3) attitude at the tip
    tip_cell: np.ndarray  # (N,) cell of the tip (-1 for the root)
    smoothness: np.ndarray  # (N,) share of Straight movements in the buffer (def. 18), root 1
    base_cost: np.ndarray  # (N,) product of per-movement costs
    cost: np.ndarray  # (N,) base cost, times (2 - smoothness) with the mode switch (6.84)
    cells_ptr: np.ndarray  # (N+1,) CSR pointers
    cells: np.ndarray  # (E,) passing cells
    cell_new: np.ndarray  # (E,) run extends the footprint
    entry: np.ndarray  # (E,) entry time of the run [s]
    leave: np.ndarray  # (E,) leave time of the run [s]
    level_ptr: np.ndarray  # (max_depth+2,) nodes of depth k are level_ptr[k]:level_ptr[k+1]
    period: float
    n_cells: int

    @property
    def n_nodes(self) -> int:
        return len(self.parent)

    @property
    def tip(self) -> np.ndarray:
        return self.samples[:, -1]

    @property
    def edge_node(self) -> np.ndarray:
        """(E,) node of every CSR entry."""
        return np.repeat(np.arange(self.n_nodes), np.diff(self.cells_ptr))

    def along_paths(self, values: np.ndarray, combine: np.ufunc) -> np.ndarray:
        """``values`` (N, ...) per node combined along every path root -> node, in place and
        returned: ``values[n] = combine(values[n], values[parent[n]])``, one tree level at a time
        (e.g. ``np.add``: path sums, ``np.minimum``: path minima, ``np.logical_or``: any on the path)."""
        lp = self.level_ptr
        for k in range(1, len(lp) - 1):
            sl = slice(lp[k], lp[k + 1])
            values[sl] = combine(values[sl], values[self.parent[sl]])
        return values

    def sample_times(self) -> np.ndarray:
        """(N, n_sub+1) time of every sample [s] from the grid's time (sample 0 = the parent tip)."""
        n_sub = self.samples.shape[1] - 1
        start = np.maximum(self.depth - 1, 0)[:, None] * self.period
        return start + self.period * np.arange(n_sub + 1)[None, :] / n_sub

    def leaves(self) -> np.ndarray:
        has_child = np.zeros(self.n_nodes, bool)
        has_child[self.parent[self.parent >= 0]] = True
        return np.flatnonzero(~has_child)

    def buffer(self, node: int) -> list[MovementType]:
        """Movements root -> node."""
        out = []
        while node > 0:
            out.append(MovementType(int(self.movement[node])))
            node = int(self.parent[node])
        return out[::-1]

    def subtree(self, node: int) -> np.ndarray:
        """(N,) mask of ``node`` and its descendants."""
        anc = np.arange(self.n_nodes)
        target = self.depth[node]
        while (self.depth[anc] > target).any():
            anc = np.where(self.depth[anc] > target, self.parent[anc], anc)
        return anc == node

    def buffers(self) -> list[tuple[int, ...]]:
        """Every node's buffer as a tuple (root: ())."""
        keys: list[tuple[int, ...]] = [()] * self.n_nodes
        for n in range(1, self.n_nodes):
            keys[n] = keys[self.parent[n]] + (int(self.movement[n]),)
        return keys

    def path_samples(self, node: int) -> np.ndarray:
        """Sampled positions root -> node, ((depth·n_sub)+1, 3), LCF."""
        chain = []
        while node > 0:
            chain.append(node)
            node = int(self.parent[node])
        if not chain:
            return self.samples[0, -1:]
        chain = chain[::-1]
        return np.concatenate([self.samples[chain[0], :1]] + [self.samples[n, 1:] for n in chain])

    def uas_entry_leave(self) -> tuple[np.ndarray, np.ndarray]:
        """(6.117/6.118): per cell, min entry / max leave time of the passing segments; 0 where
        none passes (A-14)."""
        lo = np.full(self.n_cells, np.inf)
        hi = np.full(self.n_cells, -np.inf)
        np.minimum.at(lo, self.cells, self.entry)
        np.maximum.at(hi, self.cells, self.leave)
        passed = np.isfinite(lo)
        return np.where(passed, lo, 0.0), np.where(passed, hi, 0.0)


def expand(table: PrimitiveTable, grid: AvoidanceGrid, pos: np.ndarray, att: np.ndarray, movement: np.ndarray):
    """Children of states (n,) by ``movement`` (n,): samples (n, n_sub+1, 3), end attitude, and
    the cells of samples 1..n_sub (n, n_sub) (-1 outside the grid)."""
    samples, att_end = propagate(table, pos, att, movement)
    return samples, att_end, grid.cell_index(samples[:, 1:])


def runs(sample_cells: np.ndarray, parent_tip_cell: np.ndarray, t0: np.ndarray, dt: float):
    """Runs of equal consecutive cells per row of ``sample_cells`` (n, n_sub): flat arrays of
    (row, cell, is_new, entry, leave). A run starts one sample step before its first sample
    (conservative entry) and ends at its last sample."""
    _n, m = sample_cells.shape
    prev = np.concatenate([parent_tip_cell[:, None], sample_cells[:, :-1]], axis=1)
    start = sample_cells != prev
    start[:, 0] = True
    row, col = np.nonzero(start)
    end_col = np.empty_like(col)
    end_col[:-1] = col[1:] - 1
    last_in_row = np.r_[row[1:] != row[:-1], True][: len(row)]
    end_col[last_in_row] = m - 1
    cells = sample_cells[row, col]
    is_new = (col > 0) | (cells != parent_tip_cell[row])
    entry = t0[row] + col * dt
    leave = t0[row] + (end_col + 1) * dt
    return row, cells, is_new, entry, leave


def assemble(
    grid: AvoidanceGrid,
    table: PrimitiveTable,
    parent: np.ndarray,
    movement: np.ndarray,
    pitch_cost: float,
    mode_switch: bool,
) -> ReachSetTree:
    """Recompute every bound property of a tree given by (parent, movement), nodes sorted by depth
    with the root at 0 (used after building, pruning and merging, alg. 6.4's applyCostFunction)."""
    n = len(parent)
    n_sub = table.config.n_sub
    depth = np.zeros(n, np.int64)
    for k in range(1, n):
        depth[k] = depth[parent[k]] + 1
    if np.any(np.diff(depth) < 0):
        raise ValueError("nodes must be sorted by depth")
    samples = np.zeros((n, n_sub + 1, 3))
    att = np.zeros((n, 3))
    tip_cell = np.full(n, -1, np.int64)
    smooth = np.zeros(n)
    base = np.ones(n)
    level_ptr = np.searchsorted(depth, np.arange(depth[-1] + 2))
    dt = table.duration / n_sub
    row_l, cell_l, new_l, en_l, lv_l = [], [], [], [], []
    for k in range(1, depth[-1] + 1):
        idx = np.arange(level_ptr[k], level_ptr[k + 1])
        par = parent[idx]
        m = movement[idx]
        s, a, sc = expand(table, grid, samples[par, -1], att[par], m)
        samples[idx], att[idx], tip_cell[idx] = s, a, sc[:, -1]
        smooth[idx] = smooth[par] + (m == MovementType.STRAIGHT)
        base[idx] = base[par] * np.where(table.pitching[m], pitch_cost, 1.0)
        r, c, nw, en, lv = runs(sc, tip_cell[par], (depth[par]) * table.duration, dt)
        row_l.append(idx[r])
        cell_l.append(c)
        new_l.append(nw)
        en_l.append(en)
        lv_l.append(lv)
    smoothness = np.where(depth > 0, smooth / np.maximum(depth, 1), 1.0)
    cost = base * (2.0 - smoothness) if mode_switch else base.copy()
    rows = np.concatenate(row_l) if row_l else np.zeros(0, np.int64)
    order = np.argsort(rows, kind="stable")
    counts = np.bincount(rows, minlength=n)
    cat = lambda parts, dtype: (np.concatenate(parts) if parts else np.zeros(0, dtype))[order]  # noqa: E731
    return ReachSetTree(
        parent,
        movement,
        depth,
        samples,
        att,
        tip_cell,
        smoothness,
        base,
        cost,
        np.concatenate([[0], np.cumsum(counts)]),
        cat(cell_l, np.int64),
        cat(new_l, bool),
        cat(en_l, float),
        cat(lv_l, float),
        level_ptr,
        table.duration,
        grid.n_cells,
    )
