"""``ReachSetAvoider``: the reach-set avoidance behind the shared planner protocol
(``avoidance.planner.Planner``).

Boundary of frames (converted here, once): the estimate and the threats are NED [m] from the
scenario origin; mission control works in the z-up GCF (ENU). The plan returned is NED: the end
points of the executing movement and of every planned movement, due at their movement times.

The kinematic state of a decision comes from the estimate (never truth): position; heading and
flight-path angle from the estimated ground velocity when it is at least ``heading_from_velocity``
of the planning speed (else the yaw, level); speed = the planning speed (the MA keeps speed
constant, so the segment is chosen by the commanded speed, decision D-6).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from avoidance.planner import Plan, PlanStatus, Threats
from avoidance.reachset.config import AvoidanceConfig
from avoidance.reachset.frames import heading_from_yaw_ned
from avoidance.reachset.mission import Decision, MissionControl, Restriction
from avoidance.reachset.movement import KinState, SegmentedMovementAutomaton
from guidance.mission import Mission
from sim.frames import enu_to_ned, ned_to_enu
from sim.state import VehicleState


class ReachSetAvoider:
    """Planner protocol adapter around :class:`MissionControl`; call it once per movement period."""

    name = "reachset"

    def __init__(self, mission: Mission, sma: SegmentedMovementAutomaton, cfg: AvoidanceConfig = AvoidanceConfig(),
                 cache_dir: Path | None = None, restrict: Restriction | None = None, heading_from_velocity: float = 0.5):
        self.mission = mission
        self.control = MissionControl(ned_to_enu(mission.waypoints), sma, cfg, cache_dir, restrict)
        self.speed = float(mission.cruise_speed)
        self.heading_from_velocity = heading_from_velocity
        self.last_decision: Decision | None = None

    def kin_state(self, est: VehicleState, t: float) -> KinState:
        vel = ned_to_enu(est.vel_ned)
        ground = float(np.hypot(vel[0], vel[1]))
        if ground >= self.heading_from_velocity * self.speed:
            psi, pitch = float(np.arctan2(vel[1], vel[0])), float(np.arctan2(-vel[2], ground))
        else:
            psi, pitch = heading_from_yaw_ned(est.yaw), 0.0
        return KinState(ned_to_enu(est.pos_ned), np.array([0.0, pitch, psi]), t, self.speed)

    def plan(self, estimate: VehicleState, threats: Threats, t: float) -> Plan:
        ctl = self.control
        ctl.goal = max(ctl.goal, self.mission.next_index)  # progress marked by the plan follower
        d = ctl.step(self.kin_state(estimate, t), threats)
        self.last_decision = d
        ref = d.reference
        ends = np.flatnonzero(ref.movement_end)
        pos = enu_to_ned(ref.positions[ends])
        times = ref.times[ends]
        labels = np.full(len(pos), -1)
        if not d.complete:
            near = np.linalg.norm(ref.positions[ends] - ctl.waypoints[ctl.goal], axis=1)
            if (near <= d.reach_radius).any():
                labels[int(np.argmax(near <= d.reach_radius))] = ctl.goal
        else:
            labels[-1] = len(ctl.waypoints) - 1
        vel = np.vstack([np.diff(pos, axis=0) / np.diff(times)[:, None], np.zeros((1, 3))]) if len(pos) > 1 else np.zeros((1, 3))
        run = d.run
        diag: dict[str, float | int | str] = {
            "mode": d.mode.value, "events": ";".join(d.events), "goal_index": d.goal_index,
            "category": d.runs[d.selected].categories.name if d.selected >= 0 else "",
            "feasible_nodes": int(run.fused.node_ok.sum()) if run is not None else 0,
            "buffer": "".join(str(m) for m in d.buffer), "runtime_ms": 1e3 * d.runtime_s, "complete": int(d.complete)}
        return Plan(t, pos, times, labels, PlanStatus(d.status), vel, self.name, diag)
