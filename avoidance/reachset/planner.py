"""``ReachSetAvoider``: the reach-set avoidance behind the shared planner protocol
(``sim.core.plan.Planner``).

Boundary of frames (converted here, once): the estimate and the threats are NED [m] from the
scenario origin; mission control works in the z-up GCF (ENU). The plan returned is NED: the end
points of the executing movement and of every planned movement, due at their movement times.

The kinematic state of a decision comes from the estimate (never truth): position; heading from the
estimated ground velocity when it is at least ``heading_from_velocity`` of the planning speed and
within 90 deg of the yaw (else the yaw: a vehicle moving backwards is in a transient, e.g. a
multirotor pulled back to a first plan that started at a misaligned first estimate, and a reach set
started on that course turns the whole way round) -- unless no path of the active segment's reach
sets turns: then the bearing from the estimate to the goal (D-22: a set without turns can never
correct a course error, e.g. the one flown from a misaligned first estimate); level (pitch 0: the
measured flight-path angle, carried into the executing movement's prediction, made every sink or
climb of the vehicle its own next plan, and with horizontal reach sets nothing pulled it back: the
vehicle sank to the ground); speed = the planning speed (the MA keeps speed constant, so the segment
is chosen by the commanded speed, decision D-7).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from avoidance.reachset.config import DEFAULT_AVOIDANCE, AvoidanceConfig
from avoidance.reachset.frames import GridPose, heading_from_yaw_ned
from avoidance.reachset.fusion import SpaceClass, fuse_cells
from avoidance.reachset.gridrun import Steering
from avoidance.reachset.mission import Decision, Hold, MissionControl, Restriction
from avoidance.reachset.movement import KinState, SegmentedMovementAutomaton
from sim.core.frames import enu_to_ned, ned_to_enu, wrap_pi
from sim.core.mission import Mission
from sim.core.plan import Plan, PlanStatus, Threats
from sim.core.state import VehicleState


class ReachSetAvoider:
    """Planner protocol adapter around :class:`MissionControl`; call it once per movement period."""

    name = "reachset"

    def __init__(
        self,
        mission: Mission,
        sma: SegmentedMovementAutomaton,
        cfg: AvoidanceConfig = DEFAULT_AVOIDANCE,
        cache_dir: Path | None = None,
        restrict: Restriction | None = None,
        heading_from_velocity: float = 0.5,
        turns_in_place: bool = False,
        hold: Hold | None = None,
    ):
        """``turns_in_place``: the vehicle can turn on the spot (a multirotor), so a goal inside
        the movements' turn circle is flown to on a direct leg (see :meth:`_vertices`), and it may
        stop and wait (``cfg.mission.stop_and_wait``, refused for a vehicle that cannot);
        ``hold`` as in :class:`MissionControl` (given only to a vehicle that turns in place)."""
        if hold is not None and not turns_in_place:
            raise ValueError("reachset: hold needs a vehicle that hovers and turns in place (a multirotor)")
        if cfg.mission.stop_and_wait and not turns_in_place:
            raise ValueError("reachset: stop_and_wait needs a vehicle that hovers and turns in place (a multirotor)")
        self.mission = mission
        self.turns_in_place = turns_in_place
        self.control = MissionControl(
            ned_to_enu(mission.waypoints), sma, cfg, cache_dir, restrict, advance_on_reach=False, hold=hold
        )
        self.speed = float(mission.cruise_speed)
        self.heading_from_velocity = heading_from_velocity
        self.last_decision: Decision | None = None
        self._last: Plan | None = None
        self._last_goal = -1

    def kin_state(self, est: VehicleState, t: float, goal_override: np.ndarray | None = None) -> KinState:
        """Planning state of a decision at ``t`` [s] from the estimate (GCF, ENU [m], yaw [rad]);
        ``goal_override`` (ENU [m]) as in :meth:`decide`."""
        ctl = self.control
        vel = ned_to_enu(est.vel_ned)
        ground = float(np.hypot(vel[0], vel[1]))
        yaw_psi = heading_from_yaw_ned(est.yaw)
        course = float(np.arctan2(vel[1], vel[0]))
        psi = (
            course
            if ground >= self.heading_from_velocity * self.speed and abs(wrap_pi(course - yaw_psi)) <= np.pi / 2
            else yaw_psi
        )
        pos = ned_to_enu(est.pos_ned)
        if not ctl.complete and not ctl.segment(ctl.sma.active_index(KinState(pos, np.zeros(3), t, self.speed))).turns:
            to_goal = ctl.goal_point(goal_override) - pos
            if np.hypot(to_goal[0], to_goal[1]) > 0.0:
                return KinState(pos, np.array([0.0, 0.0, float(np.arctan2(to_goal[1], to_goal[0]))]), t, self.speed)
        d = self.last_decision
        if d is not None and not d.complete and abs(t - d.t_grid) < 1e-6:
            # the heading the last decision planned for now, while the vehicle keeps within one
            # movement's yaw increment of it: re-measuring it every frame made the ±15° movements
            # chatter left/right around a straight course (S4 flew straight into the storm)
            dyaw = ctl.sma.active(KinState(pos, np.zeros(3), t, self.speed)).table.config.dyaw
            planned = d.pose.psi
            if abs(wrap_pi(psi - planned)) < dyaw:
                psi = planned
        return KinState(pos, np.array([0.0, 0.0, psi]), t, self.speed)

    def awareness(self) -> tuple[float, float] | None:
        """Range [m] from the vehicle and horizon [s] within which other traffic can be rated in
        its grids: a track whose linear prediction over the horizon stays farther than the range
        is culled exactly (``IntruderModel.reachable``). Range = grid range + one movement (the
        grid starts one movement ahead) + the intruder body and vertical margins + one centre
        spacing (half a sample along the path and half up or down); the cruise segment has the
        largest grid. ``None`` would mean: every track matters."""
        ctl = self.control
        seg = ctl.segment(ctl.sma.active_index(KinState(np.zeros(3), np.zeros(3), 0.0, self.speed)))
        models = [a.intruder_model for a in seg.assessors.values()]
        length = float(seg.grid.steps[0])
        icfg = ctl.cfg.intruders
        reach = seg.grid.range + length + icfg.body_margin + icfg.vertical_margin + max(m.step for m in models)
        return reach, max(m.horizon for m in models)

    def frame_due(self, t: float) -> bool:
        """Whether a call at ``t`` [s] makes a new decision frame: one per movement period (at the
        frame's grid time t_{i+1}, when the executing movement is over) or a waypoint just passed."""
        return (
            self._last is None
            or self.last_decision is None
            or t >= self.last_decision.t_grid - 1e-6
            or self.mission.next_index > self._last_goal
        )

    def plan(self, estimate: VehicleState, threats: Threats, t: float) -> Plan:
        """One decision frame per movement period; called more often, the last plan is returned
        until the frame is due (:meth:`frame_due`)."""
        if self._last is not None and not self.frame_due(t):
            return self._last
        return self.decide(estimate, threats, t)

    def decide(
        self,
        estimate: VehicleState,
        threats: Threats,
        t: float,
        goal_override: np.ndarray | None = None,
        emergency_threats: Threats | None = None,
    ) -> Plan:
        """A decision frame now; ``goal_override`` (ENU [m]) is flown in place of the current goal
        waypoint (the plan's labels still name the mission's own waypoints); ``emergency_threats``:
        see :meth:`MissionControl.step`."""
        ctl = self.control
        ctl.goal = max(ctl.goal, self.mission.next_index)  # progress marked by the plan follower
        d = ctl.step(self.kin_state(estimate, t, goal_override), threats, goal_override, emergency_threats)
        self.last_decision = d
        pos, times, labels = self._vertices(d, estimate, threats)
        vel = (
            np.vstack([np.diff(pos, axis=0) / np.diff(times)[:, None], np.zeros((1, 3))])
            if len(pos) > 1
            else np.zeros((1, 3))
        )
        run = d.run
        diag: dict[str, float | int | str] = {
            "mode": d.mode.value,
            "events": ";".join(d.events),
            "goal_index": d.goal_index,
            "category": d.runs[d.selected].categories.name if d.selected >= 0 else "",
            "feasible_nodes": int(run.fused.node_ok.sum()) if run is not None else 0,
            "buffer": "".join(str(m) for m in d.buffer),
            "runtime_ms": 1e3 * d.runtime_s,
            "complete": int(d.complete),
        }
        self._last = Plan(t, pos, times, labels, PlanStatus(d.status), vel, self.name, diag)
        self._last_goal = self.mission.next_index
        return self._last

    def _vertices(
        self, d: Decision, estimate: VehicleState, threats: Threats
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """NED vertices, times and labels of decision ``d``.

        The movements end on a 1-movement-length lattice, so the mission's waypoint (acceptance
        radius of the follower, usually below a movement length) is added exactly:
        - complete: hold at the last waypoint (labelled);
        - final approach (the estimate within the reach radius of the goal -- or, for a vehicle
          that turns in place, the goal anywhere inside the turn circle at the grid origin, which
          the movements reach only by flying a loop away from it and back (a wider loop flown
          passed outside the reach radius for ever) -- and no threat in the grid or the leg clear
          in a grid placed at the estimate facing the goal): a direct leg from the estimate to
          the goal;
        - otherwise the path up to its first movement end (from the executing movement's end on)
          within the reach radius of the goal, then the goal itself, if that last leg only crosses
          Free cells of the assessed grid.
        The goal vertex carries the goal's mission index; every other vertex -1."""
        ctl = self.control
        speed = max(self.speed, 1e-6)
        if d.complete:
            last = len(ctl.waypoints) - 1
            return enu_to_ned(ctl.waypoints[last:]), np.array([d.t]), np.array([last])
        goal = ctl.waypoints[ctl.goal]
        here = ned_to_enu(estimate.pos_ned)
        dist = float(np.linalg.norm(goal - here))
        direct = dist <= d.reach_radius or (self.turns_in_place and self._in_turn_circle(d, here, goal))
        if direct and (not d.threat_events or self._approach_free(d, here, goal, threats)):
            return (
                enu_to_ned(np.vstack([here, goal])),
                np.array([d.t, d.t + max(dist / speed, 1e-3)]),
                np.array([-1, ctl.goal]),
            )
        ref = d.reference
        if ref is None:
            raise RuntimeError(f"reach-set decision at t={d.t:g} s has no reference trajectory")
        ends = np.flatnonzero(ref.movement_end)
        gcf, times = ref.positions[ends], ref.times[ends]
        labels = np.full(len(gcf), -1)
        # from the executing movement's end on (= the grid origin): the current position lies
        # behind the assessed grid, so a leg from it could never be checked free
        near = np.flatnonzero(np.linalg.norm(gcf[1:] - goal, axis=1) <= d.reach_radius) + 1
        if len(near) and self._leg_free(d, gcf[near[0]], goal):
            k = int(near[0])
            gap = float(np.linalg.norm(goal - gcf[k]))
            gcf = np.vstack([gcf[: k + 1], goal])
            times = np.append(times[: k + 1], times[k] + max(gap / speed, 1e-3))
            labels = np.append(labels[: k + 1], ctl.goal)
        return enu_to_ned(gcf), times, labels

    def _in_turn_circle(self, d: Decision, here: np.ndarray, goal: np.ndarray) -> bool:
        """Whether the goal (GCF) lies inside the turn circle of the active segment's movements
        at the decision's grid pose (anywhere inside: no depth margin)."""
        ctl = self.control
        turn_radii = ctl.sma.active(KinState(here, np.zeros(3), d.t, self.speed)).table.turn_radii
        return Steering(turn_radii, d.reach_radius).in_turn_circle(d.pose.to_lcf(goal), depth=0.0)

    def _approach_free(self, d: Decision, here: np.ndarray, goal: np.ndarray, threats: Threats) -> bool:
        """Whether the direct leg here -> goal (GCF) crosses only Free cells, assessed (with the
        categories of the decision's run) in a grid placed at ``here`` facing the goal: the
        decision's own grid starts one movement ahead, behind it nothing is assessed."""
        if d.run is None:
            return False
        ctl = self.control
        seg = ctl.segment(ctl.sma.active_index(KinState(here, np.zeros(3), d.t, self.speed)))
        pose = GridPose(here, float(np.arctan2(goal[1] - here[1], goal[0] - here[0])))
        parts = seg.assessors[d.mode].assess(pose, d.t, threats)
        cls = fuse_cells(parts, d.run.categories, ctl.cfg.fusion.threshold)[-1]
        n = max(int(np.ceil(np.linalg.norm(goal - here) / 0.2)), 1)
        cells = seg.grid.cell_index(pose.to_lcf(here + np.linspace(0.0, 1.0, n + 1)[1:, None] * (goal - here)))
        return bool((cells >= 0).all() and (cls[cells] == SpaceClass.FREE).all())

    @staticmethod
    def _leg_free(d: Decision, a: np.ndarray, b: np.ndarray, spacing: float = 0.2) -> bool:
        """Whether the straight leg a -> b (GCF) lies in Free cells of the decision's grid run
        (a grid without threat events is all Free)."""
        if not d.threat_events:
            return True
        run = d.run
        if run is None or d.grid is None:
            return False
        n = max(int(np.ceil(np.linalg.norm(b - a) / spacing)), 1)
        pts = a + np.linspace(0.0, 1.0, n + 1)[:, None] * (b - a)
        lcf = d.pose.to_lcf(pts)
        cells = d.grid.cell_index(lcf)
        inside = cells >= 0
        at_origin = np.linalg.norm(lcf, axis=1) < 1e-6  # the grid's own origin (no cell)
        return bool((inside | at_origin).all() and (run.fused.space_class[cells[inside]] == SpaceClass.FREE).all())
