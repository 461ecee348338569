"""Data fusion (spec §5.6, (6.156)-(6.169), tab. 6.5) and reachability over a reach set.

Per cell: ratings in [0, 1] per source are fused into visibility, obstacle, map, intruder,
constraint and threat; Boolean properties use ``threshold`` (1e-7 in [T]); space classes
Uncertain / Occupied / Constrained / Free. Per node: reachability = Π (1 − threat) over the cells
of its footprint (each once), and a node is feasible iff that product ≥ 1 − threshold **and** every
footprint cell is Free (spec §5.6 feasibility rule). Cell reachability = max over the nodes whose
last movement passes the cell.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np

from avoidance.reachset.tree import ReachSetTree


class SpaceClass(IntEnum):
    """Cell class codes of the decision records (one per cell; Uncertain wins over Occupied,
    Occupied over Constrained)."""

    FREE = 0
    UNCERTAIN = 1
    OCCUPIED = 2
    CONSTRAINED = 3


@dataclass(slots=True)
class ThreatParts:
    """Per-source ratings of one decision, per cell (n_cells,): ``visibility`` per sensor
    (rows; none = no visibility sensor: the map is taken at full weight and no cell is
    Uncertain, decision D-4), ``obstacle`` per sensor, ``map``, ``intruders`` (one row per
    intruder), ``hard`` / ``soft`` constraint masks, and the intruders' linear predictions
    ``intruder_motion`` (one row per intruder: LCF position [m] at the grid time, LCF velocity
    [m/s], body radius [m]; the last resort of a relaxed run, D-18) with the rate [rad/s] at which
    that last resort assumes them to turn right, giving way (D-21), and the vertical margin [m]
    that stretches their bodies into vertical capsules."""

    visibility: np.ndarray  # (n_sensors, n_cells)
    obstacle: np.ndarray  # (n_sensors, n_cells)
    map: np.ndarray
    intruders: np.ndarray  # (n_intruders, n_cells)
    hard: np.ndarray
    soft: np.ndarray
    intruder_motion: np.ndarray = field(default_factory=lambda: np.zeros((0, 7)))  # (n_intruders, 7)
    give_way_turn_rate: float = 0.0
    vertical_margin: float = 0.0

    @staticmethod
    def empty(n_cells: int) -> ThreatParts:
        z = np.zeros(n_cells)
        return ThreatParts(
            np.zeros((0, n_cells)),
            np.zeros((0, n_cells)),
            z,
            np.zeros((0, n_cells)),
            np.zeros(n_cells, bool),
            np.zeros(n_cells, bool),
        )


@dataclass(frozen=True, slots=True)
class Categories:
    """Threat categories applied in one grid run (spec §6.2 steps 7-10); obstacles always."""

    intruders: bool = True
    hard: bool = True
    soft: bool = True

    @property
    def name(self) -> str:
        return "soft" if self.soft else "hard" if self.hard else "intruder" if self.intruders else "obstacle"


EMERGENCY_ORDER = (
    Categories(True, True, True),
    Categories(True, True, False),
    Categories(True, False, False),
    Categories(False, False, False),
)


@dataclass(slots=True)
class Fused:
    """Fused cell ratings, classes and reachability of one grid run."""

    visibility: np.ndarray
    obstacle: np.ndarray
    map: np.ndarray
    intruder: np.ndarray
    constraint: np.ndarray
    threat: np.ndarray
    space_class: np.ndarray  # SpaceClass per cell
    node_reach: np.ndarray  # (N,) reachability of each node (6.162)
    node_ok: np.ndarray  # (N,) feasible trajectory root -> node
    cell_reach: np.ndarray  # (n_cells,) (6.163)
    reachable: np.ndarray  # (n_cells,) Reachable cells (6.168)

    @property
    def free(self) -> np.ndarray:
        return self.space_class == SpaceClass.FREE


def fuse_cells(parts: ThreatParts, categories: Categories, threshold: float):
    """(6.156)-(6.161) and the space classes (6.164)-(6.167) -> (visibility, obstacle, map,
    intruder, constraint, threat, space_class)."""
    n = len(parts.map)
    has_sensor = len(parts.visibility) > 0
    visibility = parts.visibility.min(axis=0) if has_sensor else np.ones(n)
    obstacle = parts.obstacle.max(axis=0) * visibility if has_sensor else np.zeros(n)
    map_ = parts.map * (1.0 - visibility) if has_sensor else parts.map.copy()
    intruder = 1.0 - np.prod(1.0 - parts.intruders, axis=0) if categories.intruders else np.zeros(n)
    constraint = ((parts.hard & categories.hard) | (parts.soft & categories.soft)).astype(float)
    threat = np.maximum.reduce([obstacle, map_, intruder, constraint])
    visible = visibility >= 1.0 - threshold
    cls = np.full(n, SpaceClass.FREE, np.int8)
    cls[visible & ((constraint >= threshold) | (intruder >= threshold))] = SpaceClass.CONSTRAINED
    cls[obstacle >= threshold] = SpaceClass.OCCUPIED
    cls[~visible] = SpaceClass.UNCERTAIN
    return visibility, obstacle, map_, intruder, constraint, threat, cls


def reachability(tree: ReachSetTree, threat: np.ndarray, free: np.ndarray, threshold: float):
    """Node reachability (6.162), feasibility, cell reachability (6.163) and Reachable cells."""
    with np.errstate(divide="ignore"):
        logf = np.log1p(-np.clip(threat, 0.0, 1.0))
    entry_log = np.where(tree.cell_new, logf[tree.cells], 0.0)
    entry_bad = (tree.cell_new & ~free[tree.cells]).astype(float)
    per_node = np.zeros((tree.n_nodes, 2))
    counts = np.diff(tree.cells_ptr)
    nz = counts > 0
    if len(tree.cells):
        sums = np.add.reduceat(np.column_stack([entry_log, entry_bad]), tree.cells_ptr[:-1][nz], axis=0)
        per_node[nz] = sums
    tree.along_paths(per_node, np.add)
    node_reach = np.exp(per_node[:, 0])
    node_ok = (node_reach >= 1.0 - threshold) & (per_node[:, 1] == 0)
    node_ok[0] = False  # the empty buffer is no trajectory
    edge_node = tree.edge_node
    cell_reach = np.zeros(len(threat))
    np.maximum.at(cell_reach, tree.cells, node_reach[edge_node])
    reachable = np.zeros(len(threat), bool)
    reachable[tree.cells[node_ok[edge_node]]] = True
    return node_reach, node_ok, cell_reach, reachable & free


def fuse(tree: ReachSetTree, parts: ThreatParts, categories: Categories, threshold: float) -> Fused:
    """One grid run's assessment: fused cells + reachability over ``tree``."""
    vis, obs, map_, intr, cons, threat, cls = fuse_cells(parts, categories, threshold)
    node_reach, node_ok, cell_reach, reachable = reachability(tree, threat, cls == SpaceClass.FREE, threshold)
    return Fused(vis, obs, map_, intr, cons, threat, cls, node_reach, node_ok, cell_reach, reachable)
