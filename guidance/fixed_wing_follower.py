"""Fixed-wing plan following: leg sequencing, L1 bank command, altitude profile, airspeed.

Legs are the plan's consecutive vertices (local-level NED [m]). A leg is done when the aircraft
is within the acceptance radius of its end or has passed the line through its end perpendicular
to it; a leg of a planned turn (``turn_rates``, below), or leading into one, only at that line:
switched early, the aircraft would track the next chord before reaching it, and L1 would steer
it to the inside of the turn. Altitude demand follows the straight line between the leg's end altitudes (MSL [m]);
airspeed demand is the true airspeed [m/s] the plan commands on the leg (``airspeeds``, e.g. an
MPTP holding orbit at V_cor; past the plan's end its last leg's), else the cruise one (the flight
controller bounds every demand to the airframe's envelope). A plan with ``turn_rates`` has L1 feed the
planned turn rate forward as bank (guidance/l1.py), taken ``l1.turn_lead_s`` of flight at the
ground speed ahead along the plan so that the lagging bank is the planned one when the aircraft
gets there: written-out turns are flown on their arc rather than outside it. After the last
vertex the aircraft holds the last leg's track.
"""

from __future__ import annotations

import math

import numpy as np

from guidance.l1 import L1Guidance
from guidance.path import leg_progress
from sim.core.plan import Plan
from sim.core.setpoints import FixedWingSetpoint
from sim.core.state import VehicleState

_STRAIGHT_HEADING_ERR = math.radians(10.0)
_STRAIGHT_CROSS_M = 30.0


class FixedWingPlanFollower:
    def __init__(self, l1: L1Guidance, cruise_tas: float, acceptance_radius: float, origin_alt_m: float):
        self.l1 = l1
        self.cruise_tas = cruise_tas
        self.acceptance_radius = acceptance_radius
        self.origin_alt_m = origin_alt_m
        self.plan: Plan | None = None
        self.leg = 0
        self.cross_track_m = 0.0
        self.turning = True
        self._leg_ab: tuple[np.ndarray, np.ndarray] | None = None
        self._leg_start_m = np.zeros(1)  # path length of the plan to each vertex [m]

    def track_error(self, pos_ned: np.ndarray) -> float:
        """Signed horizontal cross-track [m] of ``pos_ned`` to the leg being followed (the
        metrics call it with the true position)."""
        return leg_progress(pos_ned, *self._leg_ab).cross_m if self._leg_ab is not None else 0.0

    def set_plan(self, plan: Plan) -> None:
        """Follow ``plan`` from its first leg (vertex 0 is where the plan's first leg starts)."""
        self.plan = plan
        self.leg = 0
        seg = np.linalg.norm(np.diff(plan.positions[:, :2], axis=0), axis=1)
        self._leg_start_m = np.concatenate([[0.0], np.cumsum(seg)])

    def _turn_rate_ahead(self, plan: Plan, along_m: float, speed_mps: float) -> float:
        """The planned turn rate [rad/s] of the leg the aircraft, ``along_m`` [m] into the current
        leg, reaches after ``l1.turn_lead_s`` at ``speed_mps`` [m/s] (0 without turn rates)."""
        if plan.turn_rates is None:
            return 0.0
        s = self._leg_start_m[self.leg] + max(along_m, 0.0) + self.l1.turn_lead_s * speed_mps
        k = int(np.searchsorted(self._leg_start_m, s, side="right")) - 1
        return float(plan.turn_rates[min(max(k, self.leg), len(plan.turn_rates) - 2)])

    def _airspeed(self, plan: Plan) -> float:
        """Airspeed demand [m/s TAS] on the current leg: the plan's (past its end, its last leg's,
        as the last leg's track is held), else cruise."""
        if plan.airspeeds is None or len(plan.positions) < 2:
            return self.cruise_tas
        return float(plan.airspeeds[min(self.leg, len(plan.positions) - 2)])

    @staticmethod
    def _in_turn(plan: Plan, leg: int) -> bool:
        """Whether ``leg`` is a piece of a planned turn or leads into one (nonzero turn rate on it
        or the next leg)."""
        return plan.turn_rates is not None and bool(np.any(plan.turn_rates[leg : leg + 2] != 0.0))

    def update(self, est: VehicleState, t: float, dt: float) -> tuple[FixedWingSetpoint, list[int]]:
        """Setpoint for now and the labels of the vertices passed since the last call
        (``t``, ``dt`` [s] are unused: the legs are geometric)."""
        plan = self.plan
        if plan is None:
            raise RuntimeError("FixedWingPlanFollower.update before any plan")
        P = plan.positions
        passed: list[int] = []
        while self.leg < len(P) - 1:
            prog = leg_progress(est.pos_ned, P[self.leg], P[self.leg + 1])
            early = prog.to_end_m <= self.acceptance_radius and not self._in_turn(plan, self.leg)
            if early or prog.along_m >= prog.length_m:
                self.leg += 1
                passed.append(int(plan.labels[self.leg]))
            else:
                break
        rate = 0.0
        if self.leg < len(P) - 1:
            a, b = P[self.leg], P[self.leg + 1]
            rate = self._turn_rate_ahead(plan, leg_progress(est.pos_ned, a, b).along_m, est.ground_speed_mps)
        elif len(P) >= 2:  # past the end: hold the last leg's track
            a, b = P[-1], 2.0 * P[-1] - P[-2]
        else:
            a, b = est.pos_ned, P[-1]
        self._leg_ab = (a, b)
        prog = leg_progress(est.pos_ned, a, b)
        roll, self.cross_track_m = self.l1.update(est, a, b, rate)
        d = a[2] + prog.fraction * (b[2] - a[2])
        heading_err = abs(math.remainder(est.course_rad - prog.bearing_rad, math.tau))
        self.turning = heading_err > _STRAIGHT_HEADING_ERR or abs(self.cross_track_m) > _STRAIGHT_CROSS_M
        sp = FixedWingSetpoint(roll_rad=roll, altitude_m=self.origin_alt_m - float(d), tas_mps=self._airspeed(plan))
        return sp, passed
