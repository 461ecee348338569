"""L1 lateral guidance along a straight segment (after ArduPilot ``AP_L1_Control``).

Frames and units: positions local NED [m], ground velocity NED [m/s] (only the horizontal
components are used); angles [rad]; lateral acceleration [m/s^2], positive = turn right;
bank command [rad], positive = right wing down; cross-track error [m], positive = aircraft right
of the segment A->B.

The L1 point lies on the track ``L1 = damping * period * V_ground / pi`` ahead (at least
``distance_min_m``); the lateral
acceleration demand is ``a = 4 damping^2 V_ground^2 / L1 * sin(nu)`` with ``nu`` the angle from
the ground velocity to the L1 point, and the bank command of a coordinated turn is
``atan(a / g)``, clipped to the roll limit. Capture from far off the segment: the approach angle
to the track is limited to 45 deg (``|sin nu1| <= 1/sqrt 2``); behind A (more than L1 away and
outside a +-135 deg arc around the track) the aircraft flies to A, and more than 3 s past B it
flies back to B. Near ``|nu| = 180 deg`` the turn direction is held to stop it flipping.

A segment that is a piece of a planned turn (a written-out arc) carries its turn rate omega
[rad/s] (+ = right): its coordinated-turn lateral acceleration ``V_tas omega`` is added to the
demand (curvature feed-forward), so on the arc L1 only corrects errors. Without it L1 on the
chords of an arc of radius R rides outside it by d with ``4 damping^2 V^2 d / L1^2 = V^2 /
(R + d)`` (about 36 m for the HAPS's L1 = 155 m and R = 257 m).
"""

from __future__ import annotations

import math
from typing import NamedTuple

from sim.core.constants import STANDARD_GRAVITY
from sim.core.state import VehicleState

_SIN_45 = math.sqrt(0.5)
_INDECISION_NU = 0.9 * math.pi


class L1Output(NamedTuple):
    """Bank command [rad] and cross-track error [m] (positive right of the segment)."""

    roll_rad: float
    cross_track_m: float


class L1Guidance:
    """L1 path follower: ``period_s`` [s] (NAVL1_PERIOD), ``damping`` (NAVL1_DAMPING),
    ``roll_limit_rad`` [rad] bank command limit, ``turn_lead_s`` [s] how early a follower feeds
    a planned turn rate forward (the airframe's bank lag behind its command), ``distance_min_m``
    [m] floor of the L1 distance (an airframe whose bank is limited further at low speed keeps L1
    about its turn radius there, or the saturated bank command limit-cycles about the track)."""

    def __init__(
        self,
        period_s: float,
        damping: float,
        roll_limit_rad: float,
        turn_lead_s: float = 0.0,
        distance_min_m: float = 1.0,
    ):
        if period_s <= 0.0 or damping <= 0.0 or roll_limit_rad <= 0.0 or distance_min_m <= 0.0:
            raise ValueError("L1 period, damping, roll limit and minimum distance must be positive")
        if turn_lead_s < 0.0:
            raise ValueError(f"L1 turn lead must be >= 0 s, got {turn_lead_s}")
        self.period_s = period_s
        self.damping = damping
        self.roll_limit_rad = roll_limit_rad
        self.turn_lead_s = turn_lead_s
        self._l1_per_speed = damping * period_s / math.pi  # L1 distance per ground speed [s]
        self.distance_min_m = distance_min_m
        self._k_l1 = 4.0 * damping * damping
        self._last_nu = 0.0

    @classmethod
    def for_airframe(cls, controller) -> L1Guidance:
        """L1 tuned for an airframe, from its controller's ``gains`` (``l1_period_s``,
        ``l1_damping``, ``roll_limit_rad``, ``l1_turn_lead_s``, ``l1_distance_min_m``)."""
        g = controller.gains
        return cls(g.l1_period_s, g.l1_damping, g.roll_limit_rad, g.l1_turn_lead_s, g.l1_distance_min_m)

    def update(self, state: VehicleState, a_ned, b_ned, turn_rate: float = 0.0) -> L1Output:
        """Bank command to follow the segment from ``a_ned`` to ``b_ned`` (NED [m]) that the path
        flies turning at ``turn_rate`` [rad/s] (+ = right; 0: a straight leg)."""
        vn, ve = float(state.vel_ned[0]), float(state.vel_ned[1])
        gs = math.hypot(vn, ve)
        if gs < 0.1:  # hovering in a head wind: use the heading
            gs = 0.1
            vn, ve = gs * math.cos(state.yaw), gs * math.sin(state.yaw)
        l1 = max(self._l1_per_speed * gs, self.distance_min_m)

        an, ae = float(a_ned[0]), float(a_ned[1])
        pn, pe = float(state.pos_ned[0]) - an, float(state.pos_ned[1]) - ae  # aircraft from A
        abn, abe = float(b_ned[0]) - an, float(b_ned[1]) - ae
        ab_len = math.hypot(abn, abe)
        if ab_len < 1e-6:  # degenerate segment: track from here to B, or along the heading
            abn, abe = abn - pn, abe - pe
            if math.hypot(abn, abe) < 1e-6:
                abn, abe = math.cos(state.yaw), math.sin(state.yaw)
        norm = math.hypot(abn, abe)
        un, ue = abn / norm, abe / norm

        cross = pe * un - pn * ue  # positive right of the track
        along = pn * un + pe * ue
        dist_a = math.hypot(pn, pe)
        if dist_a > l1 and along / max(dist_a, 1.0) < -_SIN_45:
            nu = _angle_to(vn, ve, -pn, -pe)  # behind A: fly to A
        elif along > ab_len + 3.0 * gs:
            nu = _angle_to(vn, ve, un * ab_len - pn, ue * ab_len - pe)  # past B: fly to B
        else:
            nu2 = _angle_to(vn, ve, un, ue)
            nu1 = math.asin(max(-_SIN_45, min(_SIN_45, -cross / l1)))
            nu = nu1 + nu2
        if abs(nu) > _INDECISION_NU and abs(self._last_nu) > _INDECISION_NU and nu * self._last_nu < 0.0:
            nu = self._last_nu
        self._last_nu = nu
        nu = max(-0.5 * math.pi, min(0.5 * math.pi, nu))

        tas = state.tas_mps if state.tas_mps > 0.1 else gs
        lat_acc = self._k_l1 * gs * gs / l1 * math.sin(nu) + tas * turn_rate
        roll = math.atan(lat_acc / STANDARD_GRAVITY)
        roll = max(-self.roll_limit_rad, min(self.roll_limit_rad, roll))
        return L1Output(roll, cross)


def _angle_to(vn: float, ve: float, tn: float, te: float) -> float:
    """Signed angle [rad] from the velocity (vn, ve) to the direction (tn, te), positive clockwise
    seen from above (toward the right)."""
    return math.atan2(vn * te - ve * tn, vn * tn + ve * te)
