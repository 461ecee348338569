"""Pre-computed reach sets, cached per (grid, movement set, reach-set method) (spec §4.10).

In memory for the process; optionally on disk as ``.npz`` of the (parent, movement) arrays (the
bound properties are re-assembled on load, which is cheap and keeps the file format trivial).
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from avoidance.reachset.config import GridConfig, ReachSetConfig
from avoidance.reachset.expansion import build_expansion, merge
from avoidance.reachset.grid import AvoidanceGrid
from avoidance.reachset.movement import PrimitiveTable
from avoidance.reachset.tree import ReachSetTree, assemble

_MEMORY: dict[str, ReachSetTree] = {}


def cache_key(grid: GridConfig, table: PrimitiveTable, cfg: ReachSetConfig) -> str:
    return hashlib.sha256(repr((grid, table.config, cfg)).encode()).hexdigest()[:20]


def reach_set(
    grid: AvoidanceGrid, table: PrimitiveTable, cfg: ReachSetConfig, cache_dir: Path | None = None
) -> ReachSetTree:
    """The reach set of ``cfg`` for ``grid`` and ``table``, built once."""
    key = cache_key(grid.cfg, table, cfg)
    if key in _MEMORY:
        return _MEMORY[key]
    path = Path(cache_dir) / f"reachset-{key}.npz" if cache_dir is not None else None
    if path is not None and path.exists():
        with np.load(path) as z:
            parent, movement = z["parent"], z["movement"]
    else:
        parts = [build_expansion(grid, table, p) for p in cfg.parts]
        parent, movement = parts[0] if len(parts) == 1 else merge(parts)
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            np.savez_compressed(path, parent=parent, movement=movement)
    tree = assemble(grid, table, parent, movement, cfg.pitch_cost, cfg.cost_mode_switch)
    _MEMORY[key] = tree
    return tree
