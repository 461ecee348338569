"""The trivial planner: the plan is the rest of the mission, flown at cruise speed.

It reads the estimate only to time the vertices; it avoids nothing.
"""

from __future__ import annotations

import numpy as np

from sim.core.mission import Mission
from sim.core.plan import Plan, PlanStatus, Threats
from sim.core.state import VehicleState


class FollowMissionPlanner:
    """Plan = [start of the current leg, remaining waypoints...], times at cruise speed."""

    name = "follow_mission"

    def __init__(self, mission: Mission):
        self.mission = mission

    def plan(self, estimate: VehicleState, threats: Threats, t: float) -> Plan:
        m = self.mission
        if m.waypoints_done:
            pos = m.waypoints[-1:]
            return Plan(
                t,
                pos.copy(),
                np.array([t]),
                np.array([len(m.waypoints) - 1]),
                PlanStatus.OK,
                planner=self.name,
                diagnostics={"complete": 1},
            )
        k = m.next_index
        pts = np.vstack([m.leg_start(), m.waypoints[k:]])
        labels = np.concatenate([[k - 1 if k > 0 else -1], np.arange(k, len(m.waypoints))])
        # time from the vehicle's along-track position on the first leg, then at cruise speed
        first = pts[1] - estimate.pos_ned
        dist = np.concatenate([[0.0], [np.linalg.norm(first)], np.linalg.norm(np.diff(pts[1:], axis=0), axis=1)])
        times = t + np.cumsum(dist) / m.cruise_speed
        times[0] = t
        return Plan(t, pts, times, labels, PlanStatus.OK, planner=self.name)
