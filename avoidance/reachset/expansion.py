"""Wave-front construction of a reduced reach set (alg. 6.1) with the expansion constraints of
spec §4.5-4.8 (chaotic, harmonic, ACAS-like), and the union of trees (combined, alg. 6.4).

All three constraints are the same selection with different parts: per cell, dedupe passing
nodes by a footprint key (last ``footprint_length`` cells, or the whole footprint), keep the best
by a metric (side-wall distance, or centre distance over smoothness), then keep at most
``spread_limit`` per cell. ACAS-like additionally keeps only buffers inside an enabled planar
separation (6.87/6.88). Frames: LCF of the level grid at the origin [m].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from avoidance.reachset.config import ExpansionConfig
from avoidance.reachset.grid import AvoidanceGrid
from avoidance.reachset.movement import N_MOVEMENTS, PrimitiveTable
from avoidance.reachset.movement import MovementType as M
from avoidance.reachset.tree import expand, runs

SEPARATIONS: dict[str, frozenset[M]] = {
    "horizontal": frozenset({M.STRAIGHT, M.LEFT, M.RIGHT}),
    "vertical": frozenset({M.STRAIGHT, M.UP, M.DOWN}),
    "slash": frozenset({M.STRAIGHT, M.UP_LEFT, M.DOWN_RIGHT}),
    "backslash": frozenset({M.STRAIGHT, M.UP_RIGHT, M.DOWN_LEFT}),
}


def separation_bits(names: tuple[str, ...]) -> np.ndarray:
    """(9,) bit mask per movement of the enabled separations that contain it."""
    bits = np.zeros(N_MOVEMENTS, np.int64)
    for b, name in enumerate(names):
        for m in SEPARATIONS[name]:
            bits[m] |= 1 << b
    return bits


@dataclass(slots=True)
class _Batch:
    """Nodes being built (not yet in a tree): global id, tip state and footprint keys."""

    id: np.ndarray
    pos: np.ndarray
    att: np.ndarray
    cell: np.ndarray
    depth: np.ndarray
    smooth: np.ndarray
    sep: np.ndarray
    fp: np.ndarray  # interned whole-footprint id
    tail: np.ndarray  # interned selection key: footprint (tail) [+ tip attitude]

    def take(self, idx: np.ndarray) -> _Batch:
        return _Batch(*(getattr(self, f)[idx] for f in self.__slots__))

    @staticmethod
    def concat(batches: list[_Batch]) -> _Batch:
        return _Batch(*(np.concatenate([getattr(b, f) for b in batches]) for f in _Batch.__slots__))


class _Builder:
    def __init__(self, grid: AvoidanceGrid, table: PrimitiveTable, cfg: ExpansionConfig):
        self.grid, self.table, self.cfg = grid, table, cfg
        self.sep_bits = separation_bits(cfg.separations) if cfg.method == "acas" else np.ones(N_MOVEMENTS, np.int64)
        self.parent: list[np.ndarray] = [np.array([-1])]
        self.movement: list[np.ndarray] = [np.array([-1])]
        self.depth: list[np.ndarray] = [np.array([0])]
        self.next_id = 1
        self._fp: dict = {}
        self._tail: dict = {}
        self._fp_cells: list[tuple[int, ...]] = []

    def _intern(self, table: dict, key) -> int:
        return table.setdefault(key, len(table))

    def root(self) -> _Batch:
        fp = self._intern(self._fp, (-1, ()))
        self._fp_cells.append(())
        return _Batch(
            np.array([0]),
            np.zeros((1, 3)),
            np.zeros((1, 3)),
            np.array([-1]),
            np.array([0]),
            np.array([0]),
            np.array([np.bitwise_or.reduce(self.sep_bits)]),
            np.array([fp]),
            np.array([-1]),
        )

    def children(self, b: _Batch, movements: np.ndarray) -> _Batch:
        """Expand every node of ``b`` by ``movements``; drop children leaving the grid (contained
        reach set, def. 13) or outside every enabled separation."""
        par = np.repeat(np.arange(len(b.id)), len(movements))
        mov = np.tile(movements, len(b.id))
        sep = b.sep[par] & self.sep_bits[mov]
        samples, att, sc = expand(self.table, self.grid, b.pos[par], b.att[par], mov)
        ok = np.all(sc >= 0, axis=1) & (sep != 0)
        par, mov, sep, samples, att, sc = par[ok], mov[ok], sep[ok], samples[ok], att[ok], sc[ok]
        n = len(par)
        row, cells, is_new, _, _ = runs(sc, b.cell[par], np.zeros(n), 1.0)
        new_by_row = np.split(cells[is_new], np.cumsum(np.bincount(row[is_new], minlength=n))[:-1])
        fl = self.cfg.footprint_length
        heading = np.rint(att[:, 1:] / np.maximum(self.table.d_att.max(axis=0)[1:], 1e-12)).astype(np.int64)
        fp = np.empty(n, np.int64)
        tail = np.empty(n, np.int64)
        for r in range(n):
            pf = int(b.fp[par[r]])
            new = tuple(new_by_row[r].tolist())
            fid = self._intern(self._fp, (pf, new))
            if fid == len(self._fp_cells):
                self._fp_cells.append(self._fp_cells[pf] + new)
            fp[r] = fid
            cells_key = self._fp_cells[fid][-fl:] if fl else fid
            tail[r] = self._intern(
                self._tail, (cells_key, *heading[r].tolist()) if self.cfg.attitude_key else cells_key
            )
        ids = np.arange(self.next_id, self.next_id + n)
        self.next_id += n
        self.parent.append(b.id[par])
        self.movement.append(mov)
        self.depth.append(b.depth[par] + 1)
        return _Batch(
            ids, samples[:, -1], att, sc[:, -1], b.depth[par] + 1, b.smooth[par] + (mov == M.STRAIGHT), sep, fp, tail
        )

    def metric(self, b: _Batch) -> tuple[np.ndarray, np.ndarray]:
        """(primary, secondary) selection metric, smaller is better."""
        if self.cfg.method == "chaotic":
            return self.grid.wall_distance(b.pos, b.cell), np.zeros(len(b.id))
        dist = np.linalg.norm(b.pos - self.grid.centers[b.cell], axis=1)
        smooth = b.smooth / np.maximum(b.depth, 1)
        with np.errstate(divide="ignore"):
            return np.where(smooth > 0, dist / smooth, np.inf), dist  # (6.80), A-9

    def select(self, b: _Batch) -> np.ndarray:
        """ExpansionConstraints.select over all cells of one layer: candidate indices into ``b``."""
        prim, sec = self.metric(b)
        o = np.lexsort((b.id, sec, prim, b.tail, b.cell))
        first = np.r_[True, (b.cell[o][1:] != b.cell[o][:-1]) | (b.tail[o][1:] != b.tail[o][:-1])]
        best = o[first]
        if self.cfg.spread_limit is None:
            return best
        o2 = best[np.lexsort((b.id[best], sec[best], prim[best], b.cell[best]))]
        c = b.cell[o2]
        start = np.r_[True, c[1:] != c[:-1]]
        rank = np.arange(len(o2)) - np.maximum.accumulate(np.where(start, np.arange(len(o2)), 0))
        return o2[rank < self.cfg.spread_limit]

    def build(self) -> tuple[np.ndarray, np.ndarray]:
        """Alg. 6.1; returns (parent, movement) of the kept nodes, sorted by depth, root first."""
        n_layers = self.grid.cfg.n_layers
        layer_of = self.grid.layer
        pending: dict[int, list[_Batch]] = {}
        all_moves = np.arange(N_MOVEMENTS)
        frontier, layer, selected = self.root(), -1, []
        for i in range(-1, n_layers - 1):
            if i >= 0:
                if i not in pending:
                    continue
                b = _Batch.concat(pending.pop(i))
                frontier = b.take(self.select(b))
                selected.append(frontier.id)
            moves = np.array([M.STRAIGHT]) if self.cfg.prune_last_spread and i == n_layers - 2 else all_moves
            for _ in range(1 + self.cfg.max_extra_depth):
                ch = self.children(frontier, moves)
                lay = layer_of[ch.cell]
                for target in np.unique(lay[lay > max(i, layer)]):
                    pending.setdefault(int(target), []).append(ch.take(np.flatnonzero(lay == target)))
                frontier = ch.take(np.flatnonzero(lay == i)) if i >= 0 else ch.take(np.zeros(0, np.int64))
                if len(frontier.id) == 0:
                    break
        final = np.zeros(0, np.int64)
        if n_layers - 1 in pending:
            b = _Batch.concat(pending.pop(n_layers - 1))
            final = b.id[self.select(b)]
            selected.append(final)
        return self._keep(final if self.cfg.prune_to_final_layer else np.concatenate([*selected, final]))

    def _keep(self, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        parent = np.concatenate(self.parent)
        movement = np.concatenate(self.movement)
        depth = np.concatenate(self.depth)
        marked = np.zeros(len(parent), bool)
        marked[0] = True
        front = ids
        while len(front):
            marked[front] = True
            front = parent[front]
            front = front[(front >= 0) & ~marked[np.maximum(front, 0)]]
        keep = np.flatnonzero(marked)
        keep = keep[np.argsort(depth[keep], kind="stable")]
        new_index = np.full(len(parent), -1, np.int64)
        new_index[keep] = np.arange(len(keep))
        par = parent[keep]
        return np.where(par >= 0, new_index[np.maximum(par, 0)], -1), movement[keep]


def build_expansion(grid: AvoidanceGrid, table: PrimitiveTable, cfg: ExpansionConfig) -> tuple[np.ndarray, np.ndarray]:
    """(parent, movement) of the reach set of one expansion constraint (alg. 6.1-6.3, 6.5)."""
    return _Builder(grid, table, cfg).build()


def merge(trees: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """Outer join keyed by movement (alg. 6.4): the union of the trees' buffers as one tree."""
    buffers: set[tuple[int, ...]] = set()
    for parent, movement in trees:
        keys: list[tuple[int, ...]] = [()] * len(parent)
        for n in range(1, len(parent)):
            keys[n] = keys[parent[n]] + (int(movement[n]),)
        buffers.update(keys)
    ordered = sorted(buffers, key=lambda k: (len(k), k))
    index = {k: n for n, k in enumerate(ordered)}
    parent = np.array([index[k[:-1]] if k else -1 for k in ordered], np.int64)
    movement = np.array([k[-1] if k else -1 for k in ordered], np.int64)
    return parent, movement
