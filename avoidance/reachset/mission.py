"""Mission control run (spec §6.2): waypoint handling, situation assessment, operation modes
(navigation / emergency avoidance), grid runs and movement-buffer replacement, one decision
frame per call.

Frames: z-up GCF [m] (waypoints, states), times [s]. The caller gives the state at the decision
time t_i and the sensed threats; the movement executing in [t_i, t_{i+1}) is never changed, the
grid is placed at the predicted state(t_{i+1}) (level, heading only) and the future movements
are replaced by the selected path (step 12).

Extension points for the UTM rule engine (spec §7): ``restrict`` is called with the navigation
run's context before path selection and may disable nodes (decision point "trajectory
restrictions"); ``hold`` is asked, when that restricted run found no path, whether the vehicle
may hover at the grid origin for the period instead (a soft deadlock the rules wait out); modes
and events are plain values a rule can read and set.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path

import numpy as np

from avoidance.reachset.cache import reach_set
from avoidance.reachset.config import AvoidanceConfig
from avoidance.reachset.costtogo import CostToGo
from avoidance.reachset.frames import GridPose
from avoidance.reachset.fusion import Categories, ThreatParts
from avoidance.reachset.grid import AvoidanceGrid
from avoidance.reachset.gridrun import (
    GoalCost,
    GridRun,
    Steering,
    emergency_runs,
    find_best_path,
    grid_run,
    hover_clearance,
    least_threat_path,
)
from avoidance.reachset.movement import KinState, MovementType, SegmentedMovementAutomaton
from avoidance.reachset.reference import ReferenceTrajectory, reference_trajectory
from avoidance.reachset.situation import Assessor, situation_events
from avoidance.reachset.threats.constraints import from_geofence
from avoidance.reachset.tree import ReachSetTree
from sim.core.plan import Threats


class Mode(str, Enum):
    NAVIGATION = "navigation"
    EMERGENCY = "emergency"


@dataclass(slots=True)
class SegmentPlanning:
    """Grid, reach sets and assessors of one MA segment (built once, cached)."""

    grid: AvoidanceGrid
    trees: dict[Mode, ReachSetTree]
    assessors: dict[Mode, Assessor]
    nodes: dict[Mode, dict[tuple[int, ...], int]]  # node of every buffer
    turns: bool  # some path of a reach set changes heading (False: e.g. the vertical ACAS set)


@dataclass(slots=True)
class Decision:
    """What one mission-control run decided (logged every frame)."""

    t: float
    t_grid: float
    mode: Mode
    events: list[str]
    goal_index: int
    executing: int | None
    buffer: list[MovementType]
    pose: GridPose
    grid: AvoidanceGrid | None = None
    tree: ReachSetTree | None = None
    runs: list[GridRun] = field(default_factory=list)
    selected: int = -1
    reference: ReferenceTrajectory | None = None
    status: str = "ok"
    complete: bool = False
    runtime_s: float = 0.0
    reach_radius: float = 0.0  # waypoint-reached radius of the active segment [m]
    threat_events: list[str] = field(default_factory=list)  # situation events in the grid

    @property
    def run(self) -> GridRun | None:
        """The run whose path was loaded (or the last one made if none succeeded)."""
        if not self.runs:
            return None
        return self.runs[self.selected] if self.selected >= 0 else self.runs[-1]


Restriction = Callable[[Decision, GridRun], np.ndarray | None]
Hold = Callable[[Decision, "KinState"], bool]


class MissionControl:
    """Navigation loop of one vehicle (spec §6.2, steps 1-15)."""

    def __init__(
        self,
        waypoints: np.ndarray,
        sma: SegmentedMovementAutomaton,
        cfg: AvoidanceConfig = AvoidanceConfig(),
        cache_dir: Path | None = None,
        restrict: Restriction | None = None,
        advance_on_reach: bool = True,
        hold: Hold | None = None,
    ):
        """``advance_on_reach``: step 1-2 (goal reached at the reach radius) done here; False when
        the caller owns waypoint progress (the planner adapter, whose plan follower marks waypoints
        reached within the mission's acceptance radius) and sets :attr:`goal` itself. ``hold``
        (decision, predicted state at the grid origin) -> hover there this period, asked when the
        restricted navigation run found no path (a vehicle that hovers only)."""
        self.waypoints = np.asarray(waypoints, float).reshape(-1, 3)
        self.sma, self.cfg, self.cache_dir, self.restrict, self.hold = sma, cfg, cache_dir, restrict, hold
        self.advance_on_reach = advance_on_reach
        self.goal = 0
        self.mode = Mode.NAVIGATION
        self.buffer: list[MovementType] = []
        self._segments: dict[int, SegmentPlanning] = {}
        self._cost_to_go: tuple[int, CostToGo] | None = None
        self.stop_point: np.ndarray | None = None  # GCF [m] where the vehicle hovers (D-23), None: flying
        self.stop_heading = 0.0  # grid heading [rad, GCF] of the decision that stopped it

    def segment(self, index: int) -> SegmentPlanning:
        """Grid and reach sets of MA segment ``index`` (grid scaled to its movement length)."""
        if index not in self._segments:
            table = self.sma.automata[index].table
            grid = AvoidanceGrid(self.cfg.grid.scaled(table.config.length))
            trees = {
                Mode.NAVIGATION: reach_set(grid, table, self.cfg.navigation, self.cache_dir),
                Mode.EMERGENCY: reach_set(grid, table, self.cfg.avoidance, self.cache_dir),
            }
            self._segments[index] = SegmentPlanning(
                grid,
                trees,
                {m: Assessor(grid, t, self.cfg) for m, t in trees.items()},
                {m: {b: n for n, b in enumerate(t.buffers())} for m, t in trees.items()},
                any(bool(np.any(t.tip_att[:, 2] != 0.0)) for t in trees.values()),
            )
        return self._segments[index]

    @property
    def complete(self) -> bool:
        return self.goal >= len(self.waypoints)

    def goal_point(self, goal_override: np.ndarray | None = None) -> np.ndarray:
        """Where the current goal is (ENU [m]): ``goal_override`` when given (the rules of the
        air's overtake waypoint, flown in place of the mission's), else the mission waypoint."""
        return self.waypoints[self.goal] if goal_override is None else goal_override

    def step(
        self,
        s_now: KinState,
        threats: Threats,
        goal_override: np.ndarray | None = None,
        emergency_threats: Threats | None = None,
    ) -> Decision:
        """One decision frame from the state ``s_now``; ``goal_override`` (ENU [m]) replaces the
        current goal waypoint for this frame (progress past it moves on to the mission's next).
        ``threats`` decide the mode and feed navigation runs; in emergency mode the runs see
        ``emergency_threats`` when given (a superset: the rules of the air resolve cooperative
        peers by restricting navigation runs, which emergency runs do not have, so there the peers
        must be intruders again).

        A vehicle stopped by the last decision (D-23) plans from its stop point facing the goal;
        when no path there keeps every margin (and it does not stop again), it plans with the
        heading it stopped on instead, whose grid held a soft-run path when it stopped: facing the
        goal, a relaxed run's path crossed ahead of the intruder it had stopped for (encounter 53)."""
        if self.stop_point is None:
            return self._step(s_now, threats, goal_override, emergency_threats, None)
        saved = (self.goal, self.mode, list(self.buffer), self.stop_point, self.stop_heading)
        d = self._step(s_now, threats, goal_override, emergency_threats, None)
        if d.status == "ok":
            return d
        self.goal, self.mode, self.buffer, self.stop_point, self.stop_heading = saved
        return self._step(s_now, threats, goal_override, emergency_threats, saved[4])

    def _step(
        self,
        s_now: KinState,
        threats: Threats,
        goal_override: np.ndarray | None,
        emergency_threats: Threats | None,
        heading: float | None,
    ) -> Decision:
        """:meth:`step`; ``heading`` [rad, GCF]: of a stopped vehicle's grid (None: facing the goal)."""
        t0 = time.perf_counter()
        override = goal_override
        seg_index = self.sma.active_index(s_now)
        ma = self.sma.automata[seg_index]
        length = ma.table.config.length
        events: list[str] = []
        radius = self.cfg.mission.reach_radius_lengths * length
        # 1-2: waypoint reached -> next goal
        while (
            self.advance_on_reach
            and not self.complete
            and np.linalg.norm(s_now.pos - self.goal_point(override)) <= radius
        ):
            events.append(f"waypoint_reached:{self.goal}")
            self.goal += 1
            override = None
        pose_now = GridPose(s_now.pos, float(s_now.att[2]))
        if self.complete:
            self.buffer = []
            d = Decision(
                s_now.t,
                s_now.t,
                self.mode,
                [*events, "mission_complete"],
                self.goal,
                None,
                [],
                pose_now,
                reference=reference_trajectory(ma, s_now, None, []),
                complete=True,
                reach_radius=radius,
            )
            d.runtime_s = time.perf_counter() - t0
            return d
        # 3, 6: executing movement (never changed) and the predicted state at t_{i+1}; a vehicle
        # stopped by the last decision hovers: it plans from its stop point now, facing the goal
        executing: int | None = None
        if self.stop_point is not None:
            s_next = self._facing_goal(self.stop_point, s_now.t, s_now.v, self.goal_point(override))
            if heading is not None:
                s_next = KinState(self.stop_point, np.array([0.0, 0.0, heading]), s_now.t, s_now.v)
        else:
            if not self.buffer:
                events.append("empty_buffer")
            executing = self.buffer.pop(0) if self.buffer else int(MovementType.STRAIGHT)
            s_next = ma.apply(s_now, executing)
        pose = GridPose(s_next.pos, float(s_next.att[2]))
        plan = self.segment(seg_index)
        goal_lcf = pose.to_lcf(self.goal_point(override))
        # 4-5: threat collection and situation assessment with the current mode's reach set
        parts = plan.assessors[self.mode].assess(pose, s_next.t, threats)
        threat_events = situation_events(parts, self.cfg.fusion.threshold)
        new_mode = Mode.EMERGENCY if threat_events else Mode.NAVIGATION
        if new_mode != self.mode:
            events.append(f"mode:{new_mode.value}")
            if new_mode == Mode.NAVIGATION:
                self.buffer = []  # drop the rest of the avoidance path
            self.mode = new_mode
            parts = plan.assessors[self.mode].assess(pose, s_next.t, threats)
        if self.mode == Mode.EMERGENCY and emergency_threats is not None:
            parts = plan.assessors[self.mode].assess(pose, s_next.t, emergency_threats)
            threat_events = situation_events(parts, self.cfg.fusion.threshold)
        events += threat_events
        d = Decision(
            s_now.t,
            s_next.t,
            self.mode,
            events,
            self.goal,
            executing,
            self.buffer,
            pose,
            plan.grid,
            plan.trees[self.mode],
            reach_radius=radius,
            threat_events=list(threat_events),
        )
        replan = (
            self.cfg.mission.replan_policy == "every_frame"
            or bool(threat_events)
            or not self.buffer
            or self.mode == Mode.EMERGENCY
        )
        steering = Steering(ma.table.turn_radii, radius)
        if replan:
            self._run(
                d,
                plan,
                parts,
                goal_lcf,
                steering,
                self._goal_cost(pose, s_now, threats, length, self.goal_point(override)),
            )
        seen = threats if emergency_threats is None else emergency_threats
        stop = (
            self.cfg.mission.stop_and_wait
            and self.mode == Mode.EMERGENCY
            and self._stop_pays(d, plan, parts, s_next, s_now, seen, steering, self.goal_point(override))
        ) or (
            self.hold is not None
            and self.mode == Mode.NAVIGATION
            and replan
            and d.selected < 0
            and self._hover_clear(parts, 2 * ma.table.config.period)
            and self.hold(d, s_next)
        )
        if stop and self.stop_point is None:
            self.stop_heading = pose.psi
        self.stop_point = s_next.pos.copy() if stop else None
        if stop:
            self.buffer = []
            d.events.append("stop")
            d.status = "ok"  # the hover keeps every margin
        d.reference = reference_trajectory(ma, s_now if executing is not None else s_next, executing, self.buffer)
        d.buffer = list(self.buffer)
        d.runtime_s = time.perf_counter() - t0
        return d

    @staticmethod
    def _facing_goal(pos: np.ndarray, t: float, v: float, goal: np.ndarray) -> KinState:
        """Level state at ``pos`` (GCF [m]) heading for ``goal`` (a vehicle that turns in place)."""
        return KinState(pos, np.array([0.0, 0.0, float(np.arctan2(goal[1] - pos[1], goal[0] - pos[0]))]), t, v)

    @staticmethod
    def _hover_clear(parts: ThreatParts, duration: float) -> bool:
        """Whether hovering at the grid origin for ``duration`` [s] keeps every intruder's body
        clear (straight and right-turn predictions, :func:`hover_clearance`)."""
        return hover_clearance(parts.intruder_motion, duration, parts.give_way_turn_rate, parts.vertical_margin) > 0.0

    def _stop_pays(
        self,
        d: Decision,
        plan: SegmentPlanning,
        parts: ThreatParts,
        s_next: KinState,
        s_now: KinState,
        threats: Threats,
        steering: Steering,
        goal: np.ndarray,
    ) -> bool:
        """D-23, stop and wait: whether to hover at the grid origin for the next movement period.
        The hover must keep every intruder's body clear for two periods (the hover and the next
        one, to get going again; straight and right-turn predictions). While flying, a stop is
        considered only when the path just chosen keeps every margin (soft run) but ends no
        nearer the goal than the grid origin: the reach set flies at constant speed, so a vehicle
        that must cross behind a parallel intruder it is ahead of otherwise stays beside it while
        it cannot draw ahead (finding 16); a path that gains, or a last resort (D-18, D-21: the
        others expect the right turn), is flown on. The stop is taken when waiting k periods
        (k = 1, 2, ... while the wait's flight distance, speed x k x period, is less than the
        chosen tip's cost-to-go, at most the grid's layer count), hovering clear for k + 1
        periods, then flying from the origin facing the goal, ends nearer the goal: the grid
        there k periods later holds a soft-run path whose tip's cost-to-go plus the wait's flight
        distance is below the chosen tip's. A stopped vehicle goes on hovering while no path from
        its stop point keeps every margin, and otherwise by the same comparison."""
        stopped = self.stop_point is not None
        flying_ok = d.run is not None and d.selected >= 0 and d.status == "ok"
        if not (stopped or flying_ok):
            return False
        tree, length = plan.trees[Mode.EMERGENCY], float(plan.grid.steps[0])

        def to_go(p: GridPose, lcf: np.ndarray, c: GoalCost | None) -> float:
            return float(c(lcf[None])[0]) if c is not None else float(np.linalg.norm(p.to_gcf(lcf[None])[0] - goal))

        flown = np.inf
        if flying_ok and d.run is not None:
            cost_on = self._goal_cost(d.pose, s_now, threats, length, goal)
            flown = to_go(d.pose, tree.tip[d.run.path.node], cost_on)
            if not stopped and flown < to_go(d.pose, np.zeros(3), cost_on):
                return False
        period = self.sma.automata[self.sma.active_index(s_next)].table.config.period

        def hover_clear(periods: int) -> bool:
            return self._hover_clear(parts, periods * period)

        if not hover_clear(2):
            return False
        if not flying_ok:
            return True
        for k in range(1, min(plan.grid.shape[0], int(flown / (s_next.v * period))) + 1):
            if not hover_clear(k + 1):
                return False
            waited = self._facing_goal(s_next.pos, s_next.t + k * period, s_next.v, goal)
            pose = GridPose(waited.pos, float(waited.att[2]))
            cost = self._goal_cost(pose, s_now, threats, length, goal)
            run = grid_run(
                plan.grid,
                tree,
                plan.assessors[Mode.EMERGENCY].assess(pose, waited.t, threats),
                pose.to_lcf(goal),
                Categories(),
                self.cfg.fusion.threshold,
                steering,
                cost,
            )
            if (
                run.path.ok
                and not run.path.away
                and to_go(pose, tree.tip[run.path.node], cost) + s_next.v * k * period < flown
            ):
                return True
        return False

    def _goal_cost(
        self, pose: GridPose, s_now: KinState, threats: Threats, length: float, goal: np.ndarray
    ) -> GoalCost | None:
        """Cost-to-go of LCF points to the goal around the keep-out geofences known now (D-17),
        raster L/2, built once per goal; None without such geofences (straight distance)."""
        if self._cost_to_go is None or self._cost_to_go[0] != self.goal:
            margin = self.cfg.constraints.safety_margin
            bodies = [
                c.body.buffer(margin)
                for c in (from_geofence(g, margin) for g in threats.geofences)
                if not c.keep_in and c.z_band[0] <= goal[2] <= c.z_band[1]
            ]
            if not bodies:
                return None
            self._cost_to_go = (
                self.goal,
                CostToGo(goal, bodies, 0.5 * length, self.cfg.grid.scaled(length).d_range[1] + margin, s_now.pos[:2]),
            )
        ctg = self._cost_to_go[1]
        return lambda p_lcf: ctg(pose.to_gcf(p_lcf))

    def _keep_course(
        self,
        d: Decision,
        plan: SegmentPlanning,
        goal_lcf: np.ndarray,
        steering: Steering,
        goal_cost: GoalCost | None,
        parts: ThreatParts,
    ) -> None:
        """In an emergency, the previous path's future movements stay the start of the new path
        while they are feasible in the selected run (its best continuation is chosen by alg. 6.6
        among their descendants): re-choosing freely every frame flipped between two equally good
        sides of a threat ahead, and the vehicle flew straight at it. In a run that dropped the
        intruders the continuation is the one with the largest predicted closest approach to them
        (D-18, :func:`least_threat_path`); alg. 6.6 there flew the kept course on towards them."""
        run = d.run
        node = plan.nodes[self.mode].get(tuple(self.buffer), -1) if self.buffer and d.selected >= 0 else -1
        if run is None or node <= 0 or not run.fused.node_ok[node]:
            return
        tree = plan.trees[self.mode]
        kept = dataclasses.replace(run.fused, node_ok=run.fused.node_ok & tree.subtree(node))
        if d.selected > 0 and not run.categories.intruders:
            path = least_threat_path(
                tree,
                kept,
                d.runs[d.selected - 1].fused,
                goal_lcf,
                parts.intruder_motion,
                parts.give_way_turn_rate,
                parts.vertical_margin,
            )
        else:
            path = find_best_path(plan.grid, tree, kept, goal_lcf, steering, goal_cost)
        if path.ok:
            run.path = path
            d.events.append("keep_course")

    def _run(
        self,
        d: Decision,
        plan: SegmentPlanning,
        parts: ThreatParts,
        goal_lcf: np.ndarray,
        steering: Steering,
        goal_cost: GoalCost | None,
    ) -> None:
        """Steps 7-12: grid run(s), path selection, buffer replacement."""
        threshold = self.cfg.fusion.threshold
        tree = plan.trees[self.mode]
        if self.mode == Mode.NAVIGATION:
            run = grid_run(plan.grid, tree, parts, goal_lcf, Categories(), threshold, steering, goal_cost)
            if self.restrict is not None:
                disabled = self.restrict(d, run)
                if disabled is not None:
                    run.fused.node_ok &= ~disabled
                    run.path = find_best_path(plan.grid, tree, run.fused, goal_lcf, steering, goal_cost)
            d.runs, d.selected = [run], 0 if run.path.ok else -1
        else:
            d.runs, d.selected = emergency_runs(plan.grid, tree, parts, goal_lcf, threshold, steering, goal_cost)
            self._keep_course(d, plan, goal_lcf, steering, goal_cost, parts)
        chosen = d.run
        if chosen is None:
            raise RuntimeError("mission control: the grid run step made no run")
        run = chosen
        if run.path.away:
            d.events.append("goal_in_turn_circle")
        if run.path.error == "waypoint not reachable" and self.goal < len(self.waypoints) - 1:
            d.events.append(f"waypoint_unreachable:{self.goal}")
            self.goal += 1
        if d.selected >= 0:
            self.buffer = tree.buffer(run.path.node)  # 12: flush the future, load the path
            d.status = "ok" if run.categories == Categories() else "degraded"
        else:
            d.events.append(f"no_path:{run.path.error}")
            d.status = "degraded" if self.buffer else "no_solution"
