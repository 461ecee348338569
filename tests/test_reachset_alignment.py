"""A reach set without turns (the vertical set of S8's UAS2) still reaches its goal when the
estimate starts with an alignment error: each decision's grid faces the goal from the estimate
(D-22), so the course of the first, misaligned, second is not kept for the rest of the flight."""

import numpy as np
import pytest

from avoidance.reachset.movement import multirotor_automaton
from avoidance.reachset.options import ReachSetOptions
from avoidance.reachset.planner import ReachSetAvoider
from guidance.multirotor_follower import MultirotorPlanFollower
from sim.core.mission import Mission
from sim.core.plan import Threats
from sim.core.state import VehicleState

CRUISE = 5.0  # [m/s] S8's cruise speed
GOAL = np.array([0.0, -225.0, -20.0])  # NED [m]: S8's UAS2 leg, due west
ALIGNED_AT = 1.0  # [s] first position fusion: the estimate is exact from then on


def fly(separation: str, offset: np.ndarray, yaw_error: float, t_end: float = 70.0) -> tuple[Mission, np.ndarray]:
    """Point-mass vehicle (first-order position loop + feed-forward) on the follower's carrot,
    planned at 1 Hz; before ``ALIGNED_AT`` the estimate is off by ``offset`` (NED [m]) and
    ``yaw_error`` [rad] (yaw and velocity direction). Returns the mission and the true position."""
    mission = Mission(GOAL[None, :], cruise_speed=CRUISE, acceptance_radius=1.0, start=np.zeros(3))
    opt = ReachSetOptions(period=1.0, separations=[separation])
    av = ReachSetAvoider(mission, multirotor_automaton(CRUISE, 1.0), opt.avoidance_config())
    fol = MultirotorPlanFollower(CRUISE, 2.0, 1.0, mission.acceptance_radius)
    pos, vel, dt, yaw = np.array([0.0, 0.0, -20.0]), np.zeros(3), 0.02, -np.pi / 2
    for k in range(int(t_end / dt)):
        t = k * dt
        aligned = t >= ALIGNED_AT
        err = 0.0 if aligned else yaw_error
        rot = np.array([[np.cos(err), -np.sin(err), 0.0], [np.sin(err), np.cos(err), 0.0], [0.0, 0.0, 1.0]])
        est = VehicleState(
            t=t,
            pos_ned=pos + (0.0 if aligned else offset),
            vel_ned=rot @ vel,
            euler=np.array([0.0, 0.0, yaw + err]),
            rates_body=np.zeros(3),
            alt_msl_m=420.0,
            lat_deg=47.0,
            lon_deg=8.0,
        )
        if k % round(1.0 / dt) == 0:
            fol.set_plan(av.plan(est, Threats(), t))
        sp, passed = fol.update(est, t, dt)
        yaw = sp.yaw_rad - err if np.isfinite(sp.yaw_rad) else yaw
        for label in passed:
            if label >= 0:
                mission.mark_reached(label, t)
        if mission.check_complete(t):
            break
        cmd = rot.T @ sp.vel_ned + 1.5 * (sp.pos_ned - est.pos_ned)
        n = np.linalg.norm(cmd)
        vel = cmd * min(1.0, 1.2 * CRUISE / n) if n > 0 else cmd
        pos = pos + vel * dt
    return mission, pos


@pytest.mark.parametrize("yaw_error_deg", [5.0, -5.0])
def test_vertical_set_reaches_its_goal_after_an_alignment_error(yaw_error_deg: float) -> None:
    """S8's UAS2 case: 3 m position and 5° yaw error at the first decision, a set with no turn.
    The leg (225 m) is long enough that a 5° course error (19.7 m) misses the 10 m reach radius."""
    mission, pos = fly("vertical", np.array([-3.0, 0.0, 0.0]), np.radians(yaw_error_deg))
    assert mission.complete, mission.reached
    assert np.linalg.norm(pos - GOAL) <= mission.acceptance_radius
    assert mission.completed_t is not None and mission.completed_t < 225.0 / CRUISE + 5.0


def test_vertical_set_flies_straight_without_an_alignment_error() -> None:
    """Control: no error, the same straight flight in the same time (the goal heading changes
    nothing for an aligned vehicle)."""
    mission, pos = fly("vertical", np.zeros(3), 0.0)
    assert mission.complete and np.linalg.norm(pos - GOAL) <= mission.acceptance_radius
    assert mission.completed_t is not None and mission.completed_t < 225.0 / CRUISE + 5.0
