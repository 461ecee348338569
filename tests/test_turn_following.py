"""Flying the planned turns (issue 23): L1's turn-rate feed-forward, the follower's lead, and the
controlled JSBSim experiment of sim/testbeds/turn_following.py (the HAPS at 18 km and 26 m/s on
ideal sensors flies one MPTP plan with a 40 deg right and a 40 deg left fly-over turn).

Hand numbers: R = 26^2 / (g tan 15 deg) = 257.3 m at the planning bank; L1 = 0.75 * 25 s * 26 /
pi = 155.2 m; L1 on the chords without feed-forward rides d = 36.4 m outside (d (R + d) = L1^2 /
(4 * 0.75^2)); a turn rate of 0.1 rad/s at 26 m/s is a bank of atan(2.6 / 9.80665) = 14.85 deg."""

import math

import numpy as np
import pytest

from aircraft.haps.gains import HapsGains
from guidance.fixed_wing_follower import FixedWingPlanFollower
from guidance.l1 import L1Guidance
from guidance.mptp.config import MptpConfig
from sim.core.plan import Plan
from sim.core.state import VehicleState
from sim.testbeds.turn_following import TAS_MPS, Case, course_rate_lag_s, fly, predicted_offset_m

G = 9.80665


def _northbound(north: float, speed: float = 26.0) -> VehicleState:
    """On the north axis at ``north`` [m], flying north at ``speed`` [m/s] (air and ground)."""
    return VehicleState(
        0.0, np.array([north, 0.0, -18_000.0]), np.array([speed, 0.0, 0.0]), np.zeros(3), np.zeros(3), 18e3, 0, 0, speed
    )


def test_l1_feeds_the_turn_rate_forward():
    """On the segment and along it L1 alone commands wings level; a turn rate of 0.1 rad/s adds
    its coordinated bank atan(26 * 0.1 / g) = 14.85 deg, left for a negative rate; 0.2 rad/s
    (27.9 deg) is clipped to the 20 deg limit."""
    l1 = L1Guidance(25.0, 0.75, math.radians(20.0))
    a, b = np.zeros(3), np.array([10_000.0, 0.0, 0.0])
    s = _northbound(1000.0)
    assert l1.update(s, a, b).roll_rad == pytest.approx(0.0)
    assert math.degrees(l1.update(s, a, b, 0.1).roll_rad) == pytest.approx(14.85, abs=0.01)
    assert math.degrees(l1.update(s, a, b, -0.1).roll_rad) == pytest.approx(-14.85, abs=0.01)
    assert l1.update(s, a, b, 0.2).roll_rad == pytest.approx(math.radians(20.0))
    with pytest.raises(ValueError, match="turn lead"):
        L1Guidance(25.0, 0.75, 0.3, turn_lead_s=-1.0)


@pytest.mark.parametrize(("lead_s", "leg"), [(0.0, 0), (1.3, 3), (10.0, 9)])
def test_the_follower_feeds_the_rate_of_the_leg_lead_seconds_ahead(lead_s, leg):
    """Legs of 10 m north with turn rates 0.01 k rad/s on leg k: 5 m into leg 0 at 26 m/s the
    follower feeds the rate of the leg 5 + 26 lead_s m along (leg 0 without lead, leg 3 at
    1.3 s: 38.8 m; at most the last leg); a plan without turn rates gets none."""
    pos = np.column_stack([np.arange(11) * 10.0, np.zeros(11), np.full(11, -18_000.0)])
    plan = Plan(0.0, pos, np.arange(11.0), np.full(11, -1), turn_rates=0.01 * np.arange(11.0))
    follower = FixedWingPlanFollower(L1Guidance(25.0, 0.75, math.radians(20.0), lead_s), 26.0, 1.0, 0.0)
    follower.set_plan(plan)
    sp, _ = follower.update(_northbound(5.0), 0.0, 0.1)
    assert sp.roll_rad == pytest.approx(math.atan(26.0 * 0.01 * leg / G), abs=1e-9)
    plan.turn_rates = None
    follower.set_plan(plan)
    assert follower.update(_northbound(5.0), 0.0, 0.1)[0].roll_rad == pytest.approx(0.0, abs=1e-9)


def test_legs_of_a_planned_turn_switch_only_at_their_end():
    """Legs of 30 m north, the acceptance radius 20 m: 15 m before vertex 1 the follower moves on
    when the legs are straight (no turn rates, or rates 0 on leg 0 and 1) and stays on leg 0 when
    leg 0 is a turn segment or leads into one; past the perpendicular through vertex 1 it moves
    on in every case."""
    pos = np.column_stack([np.arange(4) * 30.0, np.zeros(4), np.full(4, -18_000.0)])
    for rates, early in (
        (None, True),
        ([0.0, 0.0, 0.1, 0.0], True),
        ([0.1, 0.0, 0.0, 0.0], False),
        ([0.0, 0.1, 0.0, 0.0], False),
    ):
        plan = Plan(0.0, pos, np.arange(4.0), np.full(4, -1), turn_rates=None if rates is None else np.array(rates))
        follower = FixedWingPlanFollower(L1Guidance(25.0, 0.75, math.radians(20.0)), 26.0, 20.0, 0.0)
        follower.set_plan(plan)
        follower.update(_northbound(15.0), 0.0, 0.1)
        assert follower.leg == (1 if early else 0)
        follower.update(_northbound(30.5), 0.0, 0.1)
        assert follower.leg == 1


def test_the_predicted_l1_offset_is_the_hand_number():
    radius = MptpConfig(tas_mps=TAS_MPS).fly_over_radius_m
    assert radius == pytest.approx(257.3, abs=0.1)
    assert predicted_offset_m(25.0, 0.75, radius, TAS_MPS) == pytest.approx(36.4, abs=0.1)


@pytest.fixture(scope="module")
def fed_forward():
    return fly(Case())


@pytest.mark.closed_loop
def test_without_feed_forward_the_turns_are_flown_wide_by_the_l1_offset():
    """The cause of the wide turns: L1 on the written-out chords without the planned turn rate
    passes every turn outside by about the predicted 36.4 m (33.6 m measured: the turns are too
    short to settle) and cuts none."""
    x = fly(Case(feed_forward=False)).xte
    assert len(x) >= 14
    assert 0.8 * 36.4 < -x.min() < 1.1 * 36.4
    assert x.max() < 1.0


@pytest.mark.closed_loop
def test_with_the_planned_turn_rates_the_simulated_turns_are_flown_on_the_arc(fed_forward):
    """The simulated (5.3) turns, their rates fed forward 1.3 s ahead: no written-out vertex is
    cut by 1 m (none measured) and none is passed more than 5 m outside (3.8 m measured: the
    lead is the measured lag, not tuned to this number; 1.6 s would give 1.1 m in, 2.1 m out)."""
    assert len(fed_forward.xte) >= 14
    assert fed_forward.xte.max() < 1.0
    assert -fed_forward.xte.min() < 5.0


@pytest.mark.closed_loop
def test_the_turn_lead_is_the_hapss_course_rate_lag(fed_forward):
    """The gains' l1_turn_lead_s (1.3 s) is the lag of the HAPS's course rate behind the coordinated
    rate of its bank command, measured on the flight (1.3-1.4 s)."""
    assert course_rate_lag_s(fed_forward) == pytest.approx(HapsGains.load().l1_turn_lead_s, abs=0.15)


@pytest.mark.closed_loop
def test_a_turn_at_the_plans_issue_is_flown_wide_unless_led_in():
    """The MPTP's start turns: a plan that turns at its issue cannot be led, so the HAPS rolls in
    its 1.3 s lag late and passes the turn 12.1 m outside; the same turn after a 1.3 s (33.8 m)
    lead-in straight, the MPTP's lead-in (guidance/mptp/lead_in.py), is flown like any led turn
    (3.7 m outside; the 3 km straight gives 3.8 m). Neither is cut."""
    at_issue = fly(Case(straight_m=0.0)).xte
    led_in = fly(Case(straight_m=TAS_MPS * HapsGains.load().l1_turn_lead_s)).xte
    assert len(at_issue) == len(led_in) >= 14
    assert max(at_issue.max(), led_in.max()) < 1.0
    assert -at_issue.min() > 8.0
    assert -led_in.min() < 5.0


@pytest.mark.slow
@pytest.mark.closed_loop
@pytest.mark.parametrize(
    ("case", "outside_above", "within"),
    [
        (Case(wind_ne=(8.0, 0.0)), None, 5.0),  # cross wind: the planned (drifted) turns are flown
        (Case(wind_ne=(0.0, 8.0)), None, 5.0),  # along wind
        (Case(turn_lead_s=0.0), 8.0, None),  # the lead acts: without it the lag flies wide
        (Case("approximate"), 8.0, None),  # the bank cannot step to phi_T: the 5.2 turns are flown wide
    ],
)
def test_turn_following_factors(case, outside_above, within):
    """Cross and along wind 8 m/s: no cut, within 5 m outside (4.1 / 3.8 m measured); without the
    lead 18.1 m outside, the approximate (5.2) turns 11.7 m: wide, never cut."""
    x = fly(case).xte
    assert x.max() < 1.0
    if within is not None:
        assert -x.min() < within
    if outside_above is not None:
        assert -x.min() > outside_above
