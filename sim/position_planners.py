"""Planners for the ground station's modes: hold a position, go to a point.

Plans are in the local-level NED frame [m]; ``labels`` are -1 (no mission waypoint).
"""

from __future__ import annotations

import numpy as np

from sim.core.plan import Plan, PlanStatus, Threats
from sim.core.state import VehicleState


class HoldPositionPlanner:
    """Hover (multirotor) at ``position`` NED [m]: a one-vertex plan."""

    name = "hold"

    def __init__(self, position: np.ndarray):
        self.position = np.asarray(position, float).copy()

    def plan(self, estimate: VehicleState, threats: Threats, t: float) -> Plan:
        return Plan(t, self.position[None, :].copy(), np.array([t]), np.array([-1]), PlanStatus.OK, planner=self.name)


class GotoPlanner:
    """Straight to ``target`` NED [m] at ``speed`` [m/s] from the position where the target was
    set, then hold there."""

    name = "goto"

    def __init__(self, start: np.ndarray, target: np.ndarray, speed: float):
        self.start = np.asarray(start, float).copy()
        self.target = np.asarray(target, float).copy()
        self.speed = speed

    def plan(self, estimate: VehicleState, threats: Threats, t: float) -> Plan:
        pts = np.vstack([self.start, self.target])
        eta = t + float(np.linalg.norm(self.target - estimate.pos_ned)) / self.speed
        return Plan(t, pts, np.array([t, eta]), np.array([-1, -1]), PlanStatus.OK, planner=self.name)
