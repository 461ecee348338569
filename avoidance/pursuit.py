"""An adversarial pursuer (spec §9.3 S14, a negative test of the rules of the air): a vehicle
that broadcasts its position like any cooperative UAS but ignores the rules and flies at another
one. Each call it aims at the target's tracked position (pure pursuit) at cruise speed; until the
target is tracked it flies its mission. It never completes a mission while the target exists.
Frames: local-level NED [m], sim seconds [s].
"""

from __future__ import annotations

import numpy as np

from avoidance.follow_mission import FollowMissionPlanner
from sim.core.mission import Mission
from sim.core.plan import Plan, PlanStatus, Threats
from sim.core.state import VehicleState


class PursuitPlanner:
    name = "pursuit"

    def __init__(self, mission: Mission, target: str):
        self.mission, self.target = mission, target
        self._fallback = FollowMissionPlanner(mission)

    def plan(self, estimate: VehicleState, threats: Threats, t: float) -> Plan:
        track = next((tr for tr in threats.intruders if tr.id == self.target), None)
        if track is None:
            return self._fallback.plan(estimate, threats, t)
        aim = track.pos_ned + track.vel_ned * (t - track.t)  # where the target is now
        dist = float(np.linalg.norm(aim - estimate.pos_ned))
        return Plan(
            t,
            np.vstack([estimate.pos_ned, aim]),
            np.array([t, t + max(dist / self.mission.cruise_speed, 1e-3)]),
            np.array([-1, -1]),
            PlanStatus.OK,
            planner=self.name,
            diagnostics={"target": self.target},
        )
