"""Planners for the ground station's modes: hold a position, go to a point.

Plans are in the local-level NED frame [m]; ``labels`` are -1 (no mission waypoint). Each
planner's ``setup()`` is what it was built from (logged with its first call, ``mode_setup`` in
``/<v>/plan/input``); :func:`mode_planner` builds it again from that record (the planner re-run).
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

    def setup(self) -> dict:
        return {"position": self.position.tolist()}

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

    def setup(self) -> dict:
        return {"start": self.start.tolist(), "target": self.target.tolist(), "speed": self.speed}

    def plan(self, estimate: VehicleState, threats: Threats, t: float) -> Plan:
        pts = np.vstack([self.start, self.target])
        eta = t + float(np.linalg.norm(self.target - estimate.pos_ned)) / self.speed
        return Plan(t, pts, np.array([t, eta]), np.array([-1, -1]), PlanStatus.OK, planner=self.name)


ModePlanner = HoldPositionPlanner | GotoPlanner


def mode_planner(name: str, setup: dict) -> ModePlanner:
    """The mode planner ``name`` (``hold``, ``goto``) built from its logged ``setup()``;
    ValueError for another name."""
    if name == HoldPositionPlanner.name:
        return HoldPositionPlanner(np.asarray(setup["position"], float))
    if name == GotoPlanner.name:
        return GotoPlanner(np.asarray(setup["start"], float), np.asarray(setup["target"], float), float(setup["speed"]))
    raise ValueError(f"no ground-station mode planner {name!r} (known: hold, goto)")
