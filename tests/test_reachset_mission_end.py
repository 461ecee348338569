"""The reach-set adapter brings a plan follower exactly onto the mission's waypoints: movement ends
lie on a movement-length lattice, so without the exact goal vertex a follower with a 1 m
acceptance radius stopped short of the last waypoint and the mission never completed."""

from collections.abc import Callable

import numpy as np
import pytest

from avoidance.reachset.config import DEFAULT_AVOIDANCE, AvoidanceConfig
from avoidance.reachset.movement import multirotor_automaton
from avoidance.reachset.planner import ReachSetAvoider
from avoidance.rules.config import RulesConfig
from avoidance.rules.planner import RulesAvoider
from guidance.multirotor_follower import MultirotorPlanFollower
from sim.core.mission import Mission
from sim.core.plan import Threats
from sim.core.state import VehicleState
from sim.core.threats import IntruderTrack
from sim.planner_registry import make_planner


def fly(
    waypoints,
    planner_hz: float,
    cruise: float = 5.0,
    acceptance: float = 1.0,
    t_end: float = 80.0,
    start=(0.0, 0.0, -20.0),
    heading_deg: float = 0.0,
    speed: float = 0.0,
    turns_in_place: bool = False,
    cfg: AvoidanceConfig = DEFAULT_AVOIDANCE,
    intruder: IntruderTrack | None = None,
    estimate_error=(0.0, 0.0, 0.0),
    trace: list | None = None,
    build: Callable[[Mission], ReachSetAvoider] | None = None,
):
    """Point-mass vehicle following the carrot (first-order position loop + feed-forward), from
    ``start`` (true NED [m]) flying at ``speed`` [m/s] on ``heading_deg``. The vehicle knows its
    position as truth + ``estimate_error`` (NED [m]); ``intruder`` (true state at t = 0, flying
    straight) is sensed exactly; ``trace`` collects (t, true position, intruder position) rows.
    ``build`` makes the planner from the mission (default: a ``ReachSetAvoider`` with ``cfg`` and
    ``turns_in_place``). Returns the mission, the final true position and the planner."""
    mission = Mission(
        np.asarray(waypoints, float), cruise_speed=cruise, acceptance_radius=acceptance, start=np.zeros(3)
    )
    av = (
        build(mission)
        if build is not None
        else ReachSetAvoider(mission, multirotor_automaton(cruise, 1.0), cfg, turns_in_place=turns_in_place)
    )
    fol = MultirotorPlanFollower(cruise, 2.0, 1.0, acceptance)
    yaw = float(np.radians(heading_deg))
    error = np.asarray(estimate_error, float)
    pos, dt, t = np.array(start, float) + error, 0.02, 0.0  # the estimate the vehicle flies
    vel = speed * np.array([np.cos(yaw), np.sin(yaw), 0.0])
    every = round(1.0 / (planner_hz * dt))
    for k in range(int(t_end / dt)):
        t = k * dt
        est = VehicleState(
            t=t,
            pos_ned=pos.copy(),
            vel_ned=vel.copy(),
            euler=np.array([0.0, 0.0, yaw]),
            rates_body=np.zeros(3),
            alt_msl_m=420.0,
            lat_deg=47.0,
            lon_deg=8.0,
        )
        tracks = []
        if intruder is not None:
            at = np.asarray(intruder.pos_ned) + t * np.asarray(intruder.vel_ned)
            tracks = [IntruderTrack(intruder.id, t, at, intruder.vel_ned, intruder.radius_m)]
            if trace is not None:
                trace.append((t, pos - error, at))
        if k % every == 0:
            fol.set_plan(av.plan(est, Threats(intruders=tracks), t))
        sp, passed = fol.update(est, t, dt)
        yaw = sp.yaw_rad if np.isfinite(sp.yaw_rad) else yaw  # the vehicle turns to the follower's yaw
        for label in passed:
            if label >= 0:
                mission.mark_reached(label, t)
        if mission.check_complete(t):
            break
        cmd = sp.vel_ned + 1.5 * (sp.pos_ned - pos)
        n = np.linalg.norm(cmd)
        vel = cmd * min(1.0, 1.2 * cruise / n) if n > 0 else cmd
        pos = pos + vel * dt
    return mission, pos - error, av


def test_last_waypoint_is_reached_within_the_acceptance_radius():
    mission, pos, _ = fly([[100.0, 0.0, -20.0]], planner_hz=1.0)
    assert mission.complete and mission.completed_t < 30.0
    assert np.linalg.norm(pos - mission.waypoints[-1]) <= mission.acceptance_radius


def test_intermediate_waypoints_off_the_lattice_and_fast_planner_calls():
    wps = [[33.0, 4.0, -20.0], [70.0, 14.0, -21.0], [108.0, 10.0, -20.0]]  # goals ahead (see docs)
    for hz in (1.0, 10.0):  # called faster than the movement period: one decision per period
        mission, pos, _av = fly(wps, planner_hz=hz)
        assert mission.complete, (hz, mission.reached)
        assert [i for i, _ in mission.reached] == [0, 1, 2]
        assert np.linalg.norm(pos - mission.waypoints[-1]) <= mission.acceptance_radius


@pytest.mark.parametrize("turns_in_place", [True, False])
def test_a_goal_inside_the_turn_circle_is_flown_to_directly_by_a_vehicle_that_turns_in_place(turns_in_place):
    """Finding 12 (docs/encounters.md, encounter 72 at 61 s): at 5 m/s heading 304°, the goal
    12.8 m away 61° to the right and 2.8 m below lies inside the movements' turn circle
    (R = 19.1 m). The movements reach it only by a loop away and back (~25 s here; the JSBSim
    quadrotor flew the loop wider and orbited 11-17 m off the goal until the run ended); a
    vehicle that turns in place flies the direct leg."""
    goal = [75.0, 0.0, -20.0]
    mission, pos, _ = fly(
        [goal], 1.0, start=(62.6, -1.1, -22.8), heading_deg=-56.0, speed=5.0, t_end=40.0, turns_in_place=turns_in_place
    )
    assert mission.complete and np.linalg.norm(pos - goal) <= mission.acceptance_radius
    if turns_in_place:
        assert mission.completed_t < 6.0
    else:
        assert mission.completed_t > 15.0  # the loop


RULES = {"period": 1.0, "rules": ["detect", "resolve", "close", "head_on", "converging", "overtake"], "rules_unit": 5.0}


@pytest.mark.parametrize("registry", [True, False])
def test_the_rules_avoider_of_a_multirotor_flies_to_a_goal_inside_the_turn_circle_directly(registry):
    """Finding 12's state (above) under the rules avoider: the registry builds a multirotor's
    rules avoider with ``turns_in_place`` (direct leg, complete within 6 s); built without it, the
    same avoider flies the loop."""

    def build(mission: Mission) -> ReachSetAvoider:
        if registry:
            return make_planner("reachset", mission, "multirotor", RULES)
        return RulesAvoider(mission, multirotor_automaton(5.0, 1.0), RulesConfig(unit=5.0))

    goal = [75.0, 0.0, -20.0]
    mission, pos, av = fly(
        [goal], 1.0, start=(62.6, -1.1, -22.8), heading_deg=-56.0, speed=5.0, t_end=40.0, build=build
    )
    assert isinstance(av, RulesAvoider)
    assert mission.complete and np.linalg.norm(pos - goal) <= mission.acceptance_radius
    if registry:
        assert mission.completed_t < 6.0
    else:
        assert mission.completed_t > 15.0  # the loop
