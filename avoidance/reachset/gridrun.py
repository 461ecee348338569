"""Avoidance grid run (spec §6.1, alg. 6.6 with A-17) and the category-wise emergency runs
(spec §6.2 steps 7-11).

A trajectory "in a cell" is a feasible node whose tip lies in the cell; goal and nodes in LCF [m].
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from avoidance.reachset.fusion import EMERGENCY_ORDER, Categories, Fused, ThreatParts, fuse
from avoidance.reachset.grid import AvoidanceGrid
from avoidance.reachset.movement import MovementType
from avoidance.reachset.threats.intruders import predicted_positions, prediction_rates
from avoidance.reachset.tree import ReachSetTree


@dataclass(slots=True)
class PathResult:
    """Chosen node (-1 if none), its target cell (-1 if none), the error text if none, and
    whether the goal was out of reach inside the turn circle (the path flies away from it)."""

    node: int
    cell: int
    error: str = ""
    away: bool = False

    @property
    def ok(self) -> bool:
        return self.node >= 0


@dataclass(slots=True)
class GridRun:
    categories: Categories
    fused: Fused
    path: PathResult


@dataclass(frozen=True, slots=True)
class Steering:
    """What the Movement Automaton can reach near the grid origin: its smallest horizontal and
    vertical turn radii (R_h, R_v) [m] and the waypoint-reached radius [m] (def. 20)."""

    turn_radii: tuple[float, float]
    reach_radius: float

    def in_turn_circle(self, goal_lcf: np.ndarray, depth: float | None = None) -> bool:
        """Whether ``goal_lcf`` lies more than ``depth`` [m] inside the turn circle on its side:
        in the plane of the heading X and the goal, centre at radius R towards the goal,
        R = max(R_h |cos ψ|, R_v |sin ψ|) for the goal's direction ψ around X. ``depth`` defaults
        to the reach radius (a full-rate turn passes within the reach radius of the goals nearer
        its rim); 0 = anywhere inside."""
        margin = self.reach_radius if depth is None else depth
        x, y, z = np.asarray(goal_lcf, float)
        b = float(np.hypot(y, z))
        if b < 1e-9:
            return False
        r = max(self.turn_radii[0] * abs(y) / b, self.turn_radii[1] * abs(z) / b)
        return r > margin and x * x + (b - r) ** 2 < (r - margin) ** 2


GoalCost = Callable[[np.ndarray], np.ndarray]  # LCF points (n, 3) -> distance to the goal [m]


def straight_distance(goal_lcf: np.ndarray) -> GoalCost:
    """Alg. 6.6's own measure: the straight distance [m] of LCF points to ``goal_lcf``."""
    return lambda p: np.linalg.norm(np.asarray(p, float) - goal_lcf, axis=-1)


def find_best_path(
    grid: AvoidanceGrid,
    tree: ReachSetTree,
    fused: Fused,
    goal_lcf: np.ndarray,
    steering: Steering | None = None,
    goal_cost: GoalCost | None = None,
) -> PathResult:
    """Alg. 6.6, deterministic form (A-17): the goal cell if reachable, else the best reachable
    cell of its layer; for a goal outside the grid the reachable outer cell closest to it; then
    the cheapest feasible node ending in that cell. Ties (equal costs, as in the ACAS-like sets
    where every horizontal movement costs 1): the path whose first movement ends nearest to the
    goal, then the tip nearest to it, then smaller depth, then node order. Only the first movement
    of a path is flown before the next decision; a tie-break by depth alone picks the path that
    turns last, and replanning every frame then postpones the turn for ever.

    With ``steering``: a goal inside the turn circle that no feasible movement end comes within
    the reach radius of cannot be reached without first flying away (steering at the cell nearest
    to it turns at full rate and orbits it for ever); the path then aims straight ahead beyond
    the grid, the goal leaves the circle behind the vehicle and turning back reaches it.

    ``goal_cost`` replaces the straight distance to the goal in every ranking (cells, ties) by a
    cost-to-go around known obstacles (:mod:`avoidance.reachset.costtogo`, D-17); not used while
    aiming straight ahead."""
    ok = fused.node_ok
    tip_cells = np.unique(tree.tip_cell[ok])
    candidates = tip_cells[fused.reachable[tip_cells]]
    if len(candidates) == 0:
        return PathResult(-1, -1, "no path: empty reach set")
    away = (
        steering is not None
        and steering.in_turn_circle(goal_lcf)
        and not (np.linalg.norm(tree.tip[ok] - goal_lcf, axis=1) <= steering.reach_radius).any()
    )
    if away:
        goal_lcf = np.array([2.0 * grid.range, 0.0, 0.0])
    if away or goal_cost is None:
        goal_cost = straight_distance(goal_lcf)
    dist = goal_cost(grid.centers[candidates])
    goal_cell = int(grid.cell_index(np.asarray(goal_lcf, float)[None])[0])
    if goal_cell >= 0:
        if goal_cell in candidates:
            cell = goal_cell
        else:
            same = grid.layer[candidates] == grid.layer[goal_cell]
            if not same.any():
                return PathResult(-1, -1, "waypoint not reachable")
            cell = int(candidates[same][np.argmin(dist[same])])
    else:
        outer = grid.outer[candidates]
        if not outer.any():
            return PathResult(-1, -1, "collision: no reachable outer cell")
        cell = int(candidates[outer][np.argmin(dist[outer])])
    nodes = np.flatnonzero(ok & (tree.tip_cell == cell))
    first = nodes.copy()
    while (tree.depth[first] > 1).any():
        first = np.where(tree.depth[first] > 1, tree.parent[first], first)
    first_near = goal_cost(tree.tip[first])
    near = goal_cost(tree.tip[nodes])
    best = nodes[np.lexsort((nodes, tree.depth[nodes], near, first_near, tree.cost[nodes]))[0]]
    return PathResult(int(best), cell, away=away)


def grid_run(
    grid: AvoidanceGrid,
    tree: ReachSetTree,
    parts: ThreatParts,
    goal_lcf: np.ndarray,
    categories: Categories,
    threshold: float,
    steering: Steering | None = None,
    goal_cost: GoalCost | None = None,
) -> GridRun:
    """One assessment (fusion + reachability) and path search for one set of categories."""
    fused = fuse(tree, parts, categories, threshold)
    return GridRun(categories, fused, find_best_path(grid, tree, fused, goal_lcf, steering, goal_cost))


def emergency_runs(
    grid: AvoidanceGrid,
    tree: ReachSetTree,
    parts: ThreatParts,
    goal_lcf: np.ndarray,
    threshold: float,
    steering: Steering | None = None,
    goal_cost: GoalCost | None = None,
) -> tuple[list[GridRun], int]:
    """Steps 7-11 in selection priority order (soft, hard, intruder, obstacle paths): the runs
    made and the index of the selected one (-1 if none found). Runs stop at the first path,
    which is the one step 11 selects; a relaxed run's path is the least exposed one
    (:func:`least_threat_path`)."""
    runs = []
    for cats in EMERGENCY_ORDER:
        runs.append(grid_run(grid, tree, parts, goal_lcf, cats, threshold, steering, goal_cost))
        if runs[-1].path.ok:
            if len(runs) > 1:
                dropped = runs[-2].categories.intruders and not cats.intruders
                least = least_threat_path(
                    tree,
                    runs[-1].fused,
                    runs[-2].fused,
                    goal_lcf,
                    parts.intruder_motion if dropped else None,
                    parts.give_way_turn_rate,
                    parts.vertical_margin,
                )
                runs[-1].path = least if least.ok else runs[-1].path
            return runs, len(runs) - 1
    return runs, -1


def closest_approach(
    tree: ReachSetTree, motion: np.ndarray, right_turn_rate: float, vertical_margin: float = 0.0
) -> np.ndarray:
    """Per node (N,): the smallest predicted clearance [m] between the path root -> node and the
    intruders' bodies (``motion`` rows: LCF position at the grid time [m], velocity [m/s], body
    radius [m]; :func:`avoidance.reachset.threats.intruders.intruder_motion`), over every sample of
    the path at its own time (the root: +inf). Each intruder is predicted on its straight line and,
    with ``right_turn_rate`` > 0 [rad/s], also turning right at that rate (it gives way by the
    rules of the air, D-21); the clearance is the smaller of the two. ``vertical_margin`` [m]
    stretches each body into a vertical capsule (its centre anywhere within ± the margin of the
    predicted height)."""
    t = tree.sample_times()  # (N, S) [s]
    closest = np.full(tree.n_nodes, np.inf)
    for rate in prediction_rates(right_turn_rate):
        other = predicted_positions(
            motion[:, None, None, :3], motion[:, None, None, 3:6], t[None], rate
        )  # (I, N, S, 3)
        d = tree.samples[None] - other
        dz = np.clip(np.abs(d[..., 2]) - vertical_margin, 0.0, None)
        gap = np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2 + dz**2) - motion[:, 6, None, None]
        closest = np.minimum(closest, gap.min(axis=(0, 2)))
    closest[tree.depth == 0] = np.inf
    return tree.along_paths(closest, np.minimum)


def hover_clearance(motion: np.ndarray, period: float, right_turn_rate: float, vertical_margin: float = 0.0) -> float:
    """The smallest predicted clearance [m] between a vehicle hovering at the LCF origin over
    ``[0, period]`` [s] and the intruders' bodies (rows, rate and margin as in
    :func:`closest_approach`, sampled every tenth of the period); +inf without intruders."""
    if not len(motion):
        return float("inf")
    t = np.linspace(0.0, period, 11)
    gap = np.inf
    for rate in prediction_rates(right_turn_rate):
        p = predicted_positions(motion[:, None, :3], motion[:, None, 3:6], t[None], rate)  # (I, S, 3)
        dz = np.clip(np.abs(p[..., 2]) - vertical_margin, 0.0, None)
        gap = min(gap, float((np.sqrt(p[..., 0] ** 2 + p[..., 1] ** 2 + dz**2) - motion[:, 6, None]).min()))
    return gap


def straight_speed(tree: ReachSetTree) -> float:
    """The planning speed [m/s]: the reach of the farthest first movement (Straight) per period."""
    return float(tree.tip[tree.depth == 1, 0].max() / tree.period)


def passing_on_the_right(motion: np.ndarray, speed: float) -> np.ndarray:
    """Per intruder (rows as in :func:`closest_approach`): whether its straight-line prediction
    passes the vehicle flying straight on at ``speed`` [m/s] (LCF X) on the right, clear of its
    body: the horizontal relative position at the closest approach (now, if they separate) lies
    more than the body radius to the right (LCF Y < -radius)."""
    rel = motion[:, :2]
    vel = motion[:, 3:5] - np.array([speed, 0.0])
    vv = np.einsum("ij,ij->i", vel, vel)
    tcpa = np.clip(-np.einsum("ij,ij->i", rel, vel) / np.where(vv > 0.0, vv, 1.0), 0.0, None)
    return rel[:, 1] + tcpa * vel[:, 1] < -motion[:, 6]


def least_threat_path(
    tree: ReachSetTree,
    fused: Fused,
    stricter: Fused,
    goal_lcf: np.ndarray,
    intruder_motion: np.ndarray | None = None,
    give_way_turn_rate: float = 0.0,
    vertical_margin: float = 0.0,
) -> PathResult:
    """The path of a relaxed run (a threat category dropped because no path respects it, spec
    §6.2 step 11): of the full-length trajectories feasible in ``fused``, the one least exposed to
    the dropped threats (smallest sum of the threat ratings of its footprint cells in the
    ``stricter`` run), then the one feasible there for the most movements (time to re-plan), then
    the tip nearest the goal. Steering at the goal alone flew straight through the intruder,
    building margin or storm that made the stricter run fail.

    With ``intruder_motion`` (the intruders were dropped, rows as in :func:`closest_approach`)
    and a ``give_way_turn_rate`` > 0, first the paths that never turn left of the heading, as the
    others are assumed to turn right, if the set can turn right level (a set whose right turns
    descend, like the slash set, would trade the level convention for a height change the others
    cannot foresee) and some intruder is not already passing on the right
    (:func:`passing_on_the_right`: turning right would then cross ahead of every one of them, the
    passes the convention exists to avoid) (D-21); then the path with the largest predicted clearance to the intruders'
    bodies, rounded to 1 cm (D-18), each intruder on its straight line and turning right at
    ``give_way_turn_rate`` [rad/s], bodies stretched by ``vertical_margin`` [m]
    (:func:`closest_approach`). The exposure to the intruder space
    (line, body, time window) does not say which side is farther from the aircraft: two vehicles
    in each other's space chose independently and flew side by side (S8). Against straight lines
    alone, two converging vehicles each passed behind the other and turned into each other."""
    leaves = tree.leaves()
    cand = leaves[fused.node_ok[leaves]]
    if len(cand) == 0:
        return PathResult(-1, -1, "no full-length path")
    entry = np.where(tree.cell_new, stricter.threat[tree.cells], 0.0)
    exposure = np.zeros(tree.n_nodes)
    counts = np.diff(tree.cells_ptr)
    nz = counts > 0
    if len(tree.cells):
        exposure[nz] = np.add.reduceat(entry, tree.cells_ptr[:-1][nz])
    tree.along_paths(exposure, np.add)
    clear = tree.along_paths(stricter.node_ok.astype(np.int64), np.add)  # feasibility is prefix-closed: clear movements
    near = np.linalg.norm(tree.tip[cand] - goal_lcf, axis=1)
    keys = [cand, near, -clear[cand], np.round(exposure[cand], 9)]
    if intruder_motion is not None and len(intruder_motion):
        clearance = closest_approach(tree, intruder_motion, give_way_turn_rate, vertical_margin)
        keys.append(-np.round(clearance[cand], 2))
        if (
            give_way_turn_rate > 0.0
            and (tree.movement == MovementType.RIGHT).any()
            and not passing_on_the_right(intruder_motion, straight_speed(tree)).all()
        ):
            left = tree.along_paths(tree.tip_att[:, 2] > 1e-9, np.logical_or)  # ever left of the heading
            keys.append(left[cand])
    best = int(cand[np.lexsort(keys)[0]])
    return PathResult(best, int(tree.tip_cell[best]))
