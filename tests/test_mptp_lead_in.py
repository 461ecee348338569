"""The MPTP's lead-in (guidance/mptp/lead_in.py): each replan searches from the state predicted
``start_lead_s`` ahead, the current turn held, so that the follower can lead the plan's first
turn. Hand geometry: the HAPS at 26 m/s heading north, 1.3 s lead = 33.8 m."""

import math

import numpy as np
import pytest
from shapely.geometry import box

from guidance.mptp.config import MptpConfig
from guidance.mptp.lead_in import held_turn_rate, lead_in
from guidance.mptp.planner import MptpPlanner
from sim.core.constants import STANDARD_GRAVITY
from sim.core.mission import Mission
from sim.core.plan import Threats
from sim.core.state import VehicleState
from sim.core.threats import StormSnapshot
from sim.planner_registry import make_planner

V = 26.0
MISSION = Mission(np.array([[0.0, 5_000.0, -18_000.0]]), V, 10.0)  # the goal east, 5 km
STORMS = [StormSnapshot(0.0, (box(-40_000.0, -40_000.0, -38_000.0, -38_000.0),), np.zeros((1, 2)))]


def _northbound(roll_deg: float = 0.0) -> VehicleState:
    euler = np.array([math.radians(roll_deg), 0.0, 0.0])
    pos = np.array([0.0, 0.0, -18_000.0])
    return VehicleState(0.0, pos, np.array([V, 0.0, 0.0]), euler, np.zeros(3), 18_000.0, 47.0, 8.0, V)


def test_straight_lead_in_is_the_speed_times_the_lead():
    li = lead_in(np.array([10.0, 20.0]), 5.0, math.radians(30.0), 0.0, V, 1.3)
    assert li.p == pytest.approx([10.0 + 33.8 * math.cos(math.radians(30.0)), 20.0 + 33.8 * 0.5])
    assert (li.t, li.course) == pytest.approx((6.3, math.radians(30.0)))


def test_turning_lead_in_is_the_arc_at_the_held_rate():
    """A right turn held for a quarter circle from north ends R north and R east, heading east;
    a left one R north and R west."""
    rate = held_turn_rate(math.radians(15.0), V, STANDARD_GRAVITY)
    r = V / rate
    assert r == pytest.approx(V**2 / (STANDARD_GRAVITY * math.tan(math.radians(15.0))))  # 257.26 m
    quarter = 0.5 * math.pi / rate
    right = lead_in(np.zeros(2), 0.0, 0.0, rate, V, quarter)
    left = lead_in(np.zeros(2), 0.0, 0.0, -rate, V, quarter)
    assert right.p == pytest.approx([r, r]) and right.course == pytest.approx(0.5 * math.pi)
    assert left.p == pytest.approx([r, -r]) and left.course == pytest.approx(-0.5 * math.pi)


def test_the_plan_starts_its_first_turn_after_the_lead():
    """With the lead the plan's first leg is the predicted straight flight (no turn on it), and
    the turn towards the goal starts at its end, 1.3 s and 33.8 m on, and rolls in as the
    unled plan's does. Without the lead the turn starts at the plan's issue."""
    est = _northbound()
    led = MptpPlanner(MISSION, MptpConfig(turn_model="simulated", start_lead_s=1.3)).plan(est, Threats(STORMS), 0.0)
    now = MptpPlanner(MISSION, MptpConfig(turn_model="simulated")).plan(est, Threats(STORMS), 0.0)
    assert now.turn_rates[0] > 0.0  # the right turn to the goal begins at once
    assert led.positions[1, :2] == pytest.approx([33.8, 0.0], abs=1e-6)
    assert (led.times[1], led.turn_rates[0]) == pytest.approx((1.3, 0.0))
    assert led.turn_rates[1] == pytest.approx(now.turn_rates[0])
    assert led.positions[2:5, :2] - led.positions[1, :2] == pytest.approx(now.positions[1:4, :2], abs=0.5)
    assert led.diagnostics["start_lead_s"] == 1.3


def test_the_lead_in_holds_the_current_bank():
    """Banked 10 deg left when the plan is made: the lead-in leg turns left at g tan(10 deg) / V
    and ends on that arc."""
    est = _northbound(-10.0)
    plan = MptpPlanner(MISSION, MptpConfig(turn_model="simulated", start_lead_s=1.3)).plan(est, Threats(STORMS), 0.0)
    rate = -STANDARD_GRAVITY * math.tan(math.radians(10.0)) / V
    assert plan.turn_rates[0] == pytest.approx(rate)
    want = lead_in(np.zeros(2), 0.0, 0.0, rate, V, 1.3).p
    assert plan.positions[1, :2] == pytest.approx(want) and want[1] < -1.0


def test_the_engine_leads_the_fly_over_models_by_the_followers_turn_lead():
    """Built by the registry with the airframe's turn lead: the fly-over models take it, the
    simple model's fly-by corners none, and a scenario's own start_lead_s wins."""

    def lead(options: dict) -> float:
        return make_planner("mptp", MISSION, "fixed_wing", options, turn_lead_s=1.3).cfg.start_lead_s

    assert lead({"turn_model": "simulated"}) == lead({"turn_model": "approximate"}) == 1.3
    assert lead({}) == 0.0
    assert lead({"turn_model": "simulated", "start_lead_s": 2.0}) == 2.0


def test_negative_start_lead_is_one_clear_error():
    with pytest.raises(ValueError, match="start_lead_s must be >= 0"):
        MptpConfig(start_lead_s=-1.0)
