"""Multirotor plan following: a carrot that moves along the plan at cruise speed.

With ``step=True`` the carrot jumps to each vertex instead (a position step, as in a position
mode "go to" or a step-response test).

The carrot is a point on the plan's polyline (local-level NED [m]) advanced at the cruise speed,
slowed on climbing/descending legs so that the vertical rate stays within the climb/descent
limits [m/s]. It waits at each vertex until the vehicle is within the acceptance radius [m]
(the vertex then counts as passed), hovers there for the vertex's hold time [s], and never runs
more than ``max_lead_m`` ahead of the vehicle. Setpoint: carrot position, carrot velocity as
feed-forward, yaw from ``yaw_rad`` of the vertex the leg ends at if given, else along the
horizontal leg direction (held on vertical legs).
"""

from __future__ import annotations

import math

import numpy as np

from sim.core.plan import Plan
from sim.core.setpoints import MultirotorSetpoint
from sim.core.state import VehicleState


def _project(points: np.ndarray, cum: np.ndarray, p: np.ndarray) -> float:
    """Arc length [m] of the point of the polyline nearest to ``p``."""
    a, b = points[:-1], points[1:]
    ab = b - a
    L2 = np.einsum("ij,ij->i", ab, ab)
    u = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.where(L2 > 0, L2, 1.0), 0.0, 1.0)
    d = np.linalg.norm(a + u[:, None] * ab - p, axis=1)
    k = int(np.argmin(d))
    return float(cum[k] + u[k] * math.sqrt(L2[k]))


class MultirotorPlanFollower:
    def __init__(
        self,
        cruise_speed: float,
        max_climb: float,
        max_descent: float,
        acceptance_radius: float,
        hold_s: dict[int, float] | None = None,
        yaw_rad: dict[int, float] | None = None,
        max_lead_m: float = 5.0,
        step: bool = False,
    ):
        """``hold_s`` / ``yaw_rad``: hover time [s] / yaw [rad] at the vertices labelled with these
        mission waypoint indices (replace them with :meth:`set_waypoint_attributes` when the
        mission changes)."""
        self.cruise_speed = cruise_speed
        self.max_climb = max_climb
        self.max_descent = max_descent
        self.acceptance_radius = acceptance_radius
        self.hold_s = hold_s or {}
        self.yaw_rad = yaw_rad or {}
        self.step = step
        self.max_lead_m = max_lead_m
        self.plan: Plan | None = None
        self._cum = np.zeros(1)
        self.s = 0.0  # carrot arc length along the current plan [m]
        self.leg = 0
        self.carrot: np.ndarray | None = None
        self._hold_until = -math.inf
        self._arrived = False
        self._yaw = float("nan")
        self.cross_track_m = 0.0
        self.turning = False
        self._leg_au: tuple[np.ndarray, np.ndarray] | None = None

    def set_waypoint_attributes(self, hold_s: dict[int, float], yaw_rad: dict[int, float]) -> None:
        """New waypoint holds and yaws (a new mission); a hold under way ends with the old one."""
        self.hold_s, self.yaw_rad = hold_s, yaw_rad
        self._hold_until = -math.inf
        self._arrived = False

    def set_plan(self, plan: Plan) -> None:
        """Follow ``plan``, continuing from where the carrot is (projected onto the new plan)."""
        P = plan.positions
        self._cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
        self.plan = plan
        if self.carrot is not None and len(P) > 1:
            self.s = _project(P, self._cum, self.carrot)
        else:
            self.s = 0.0
        # a carrot exactly at a vertex stays on the leg ending there, so the vertex is still passed
        self.leg = min(max(int(np.searchsorted(self._cum, self.s, side="left")) - 1, 0), max(len(P) - 2, 0))
        self._arrived = False

    def _leg_speed(self, u: np.ndarray) -> float:
        """Cruise speed (or the plan's lower commanded speed), reduced so that the vertical rate of
        unit direction ``u`` is in limits."""
        v = self.cruise_speed
        if self.plan is not None and self.plan.speed is not None:
            v = min(v, self.plan.speed)
        if u[2] < -1e-9:
            v = min(v, self.max_climb / -u[2])
        elif u[2] > 1e-9:
            v = min(v, self.max_descent / u[2])
        return v

    def update(self, est: VehicleState, t: float, dt: float) -> tuple[MultirotorSetpoint, list[int]]:
        """Setpoint for now and the labels of the vertices passed since the last call."""
        plan = self.plan
        if plan is None:
            raise RuntimeError("MultirotorPlanFollower.update before any plan")
        P, cum, pos = plan.positions, self._cum, est.pos_ned
        passed: list[int] = []
        if len(P) == 1:
            self.carrot = P[0].copy()
            self.turning = True
            return MultirotorSetpoint(self.carrot.copy(), np.zeros(3), self._yaw), passed
        vel = np.zeros(3)
        if t >= self._hold_until:
            at_vertex = self.s >= cum[self.leg + 1] - 1e-9
            if at_vertex:
                end = P[self.leg + 1]
                if not self._arrived and np.linalg.norm(pos - end) <= self.acceptance_radius:
                    label = int(plan.labels[self.leg + 1])
                    passed.append(label)
                    self._arrived = True
                    self._hold_until = t + self.hold_s.get(label, 0.0)
                if self._arrived and t >= self._hold_until and self.leg + 2 < len(P):
                    self.leg += 1
                    self._arrived = False
            elif self.step:
                self.s = float(cum[self.leg + 1])
            else:
                a, u = P[self.leg], _leg_unit(P, self.leg)
                if np.linalg.norm(a + u * (self.s - cum[self.leg]) - pos) < self.max_lead_m:
                    v = self._leg_speed(u)
                    self.s = min(self.s + v * dt, cum[self.leg + 1])
                    vel = u * v
        a, u = P[self.leg], _leg_unit(P, self.leg)
        self.carrot = a + u * (self.s - cum[self.leg])
        end_label = int(plan.labels[self.leg + 1])
        if end_label in self.yaw_rad:
            self._yaw = self.yaw_rad[end_label]
        elif math.hypot(u[0], u[1]) > 0.2:
            self._yaw = math.atan2(u[1], u[0])
        self._leg_au = (a, u)
        self.cross_track_m = self.track_error(pos)
        self.turning = not vel.any()
        return MultirotorSetpoint(self.carrot.copy(), vel, self._yaw), passed

    def track_error(self, pos_ned: np.ndarray) -> float:
        """3-D distance [m] of ``pos_ned`` from the line of the leg being followed (the metrics
        call it with the true position)."""
        if self._leg_au is None:
            return 0.0
        a, u = self._leg_au
        ap = pos_ned - a
        r = ap - u * float(ap @ u)
        return math.sqrt(r.dot(r))  # np.linalg.norm's arithmetic, without its dispatch


def _leg_unit(positions: np.ndarray, leg: int) -> np.ndarray:
    """Unit vector along leg ``leg`` of the (N, 3) polyline ``positions`` (zero for a null leg)."""
    seg = positions[leg + 1] - positions[leg]
    n = float(np.linalg.norm(seg))
    return seg / n if n > 0 else np.zeros(3)
