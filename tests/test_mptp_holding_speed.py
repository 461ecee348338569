"""MPTP holding with the speed correction V_cor and pre-defined holding locations (seed 002, 5.4),
against the thesis's numbers and hand-computed orbits."""

import math

import numpy as np
import pytest
from shapely.geometry import box

from guidance.fixed_wing_follower import FixedWingPlanFollower
from guidance.l1 import L1Guidance
from guidance.mptp.config import MptpConfig
from guidance.mptp.holding import (
    ARC_POINTS,
    circumradius_m,
    corrected_orbit,
    corrected_speed_mps,
    holding_bank,
    rate_one_dt_s,
    speed_correction,
)
from guidance.mptp.planner import MptpPlanner
from sim.core.mission import Mission
from sim.core.plan import Plan, PlanStatus, Threats
from sim.core.threats import StormSnapshot
from sim.testbeds.mptp_holding_speed import hold_flight
from sim.testbeds.mptp_openloop import vehicle_state


def test_speed_correction_against_the_thesis_numbers():
    """Eqs. 5.76-5.84 for the thesis's aircraft (80 m/s, |dchi| 45 deg, n = 8). dV = S_cc / S_n
    = (pi / 4) / (2 sin 22.5 deg) = 1.02617: V_cor = 82.09 m/s (the thesis prints 82.04, which
    is 1 + (S_cc - S_n) / S_cc, the second form of its eq. 5.78). A rate-one lap (120 s) needs
    dt = 120 s / 8 = 15 s exactly (thesis 14.99 s from the rounded V_cor), R_cc = 1567.9 m (thesis
    1566.86 m) and a bank of 23.67 deg (thesis 23.67 deg)."""
    assert speed_correction(math.pi / 4) == pytest.approx(1.026172, abs=1e-6)
    thesis = MptpConfig.thesis()
    assert corrected_speed_mps(thesis) == pytest.approx(82.094, abs=1e-3)
    assert rate_one_dt_s(thesis) == pytest.approx(15.0)
    rot = MptpConfig.thesis(dt_s=15.0)
    assert circumradius_m(rot) == pytest.approx(82.094 * 120.0 / (2 * math.pi), abs=0.1)
    assert circumradius_m(rot) == pytest.approx(1567.9, abs=0.1)
    assert math.degrees(holding_bank(rot)) == pytest.approx(23.67, abs=0.01)
    assert holding_bank(rot) <= rot.bank_max


def test_corrected_orbit_reaches_each_state_after_dt_on_its_circle():
    """The HAPS (26 m/s, dt 60 s, 45 deg): S_n = 1560 m, R_cc = 1560 / (2 sin 22.5 deg) =
    2038.2 m, V_cor = 26.68 m/s; from (1000, 2000) heading east turning right the circle's centre
    is 2038.2 m south; the state after one leg is 1560 m away on course 112.5 deg, reached at
    t0 + 60 s; a lap of 8 legs returns to the start at t0 + 480 s."""
    cfg = MptpConfig(hold_speed_correction=True)
    p0, t0 = np.array([1000.0, 2000.0]), 100.0
    pts, times, courses = corrected_orbit(p0, t0, math.pi / 2, 8, cfg, 1.0)
    r_cc = 1560.0 / (2 * math.sin(math.radians(22.5)))
    assert circumradius_m(cfg) == pytest.approx(r_cc) and r_cc == pytest.approx(2038.2, abs=0.1)
    centre = p0 + np.array([-r_cc, 0.0])
    np.testing.assert_allclose(np.linalg.norm(pts - centre, axis=1), r_cc)
    state = pts[::ARC_POINTS]
    np.testing.assert_allclose(times[::ARC_POINTS], t0 + 60.0 * np.arange(9))
    chi = math.radians(112.5)
    np.testing.assert_allclose(state[1], p0 + 1560.0 * np.array([math.cos(chi), math.sin(chi)]), atol=1e-6)
    np.testing.assert_allclose(state[8], p0, atol=1e-6)
    # the arc between two plan points, over its time, is flown at V_cor
    arc = r_cc * math.radians(45.0) / ARC_POINTS
    np.testing.assert_allclose(arc / np.diff(times), corrected_speed_mps(cfg))
    assert corrected_speed_mps(cfg) == pytest.approx(26.0 * 1.026172, abs=1e-4)
    assert courses[ARC_POINTS] == pytest.approx(math.radians(135.0))


def _covered_goal(cfg: MptpConfig, est_course: float = 0.0):
    """A static cell over the goal 21 km north for the whole horizon: the plan must hold."""
    storm = StormSnapshot(0.0, (box(18_000, -3000, 24_000, 3000),), None)
    mission = Mission(np.array([[21_000.0, 0.0, 0.0]]), cfg.tas_mps, 500.0)
    return MptpPlanner(mission, cfg).plan(
        vehicle_state(0.0, np.zeros(2), est_course, cfg.tas_mps), Threats(storms=[storm]), 0.0
    )


HOLD_CFG = MptpConfig(safety_single_m=(2000.0,) * 3, sigma_front_mps=0.0, sigma_back_mps=0.0)


def test_the_planner_holds_on_the_corrected_circle_when_the_goal_is_covered():
    plain, corrected = _covered_goal(HOLD_CFG), _covered_goal(HOLD_CFG.with_(hold_speed_correction=True))
    for plan in (plain, corrected):
        assert plan.status == PlanStatus.DEGRADED and plan.diagnostics["reason"] == "goal covered"
    ne, t = corrected.positions[:, :2], corrected.times
    r_cc = circumradius_m(HOLD_CFG)
    # heading north from the origin turning right: the centre is r_cc east; a state every dt
    np.testing.assert_allclose(np.linalg.norm(ne - [0.0, r_cc], axis=1), r_cc, atol=1e-6)
    np.testing.assert_allclose(t[::ARC_POINTS], HOLD_CFG.dt_s * np.arange(len(t[::ARC_POINTS])))
    assert t[-1] >= HOLD_CFG.replan_period_s
    # both have states S_n = V dt = 1560 m apart every dt; the uncorrected orbit flies their
    # chords at V (after its start turn), the corrected one the arcs between them at V_cor
    np.testing.assert_allclose(np.linalg.norm(np.diff(ne[::ARC_POINTS], axis=0), axis=1), HOLD_CFG.leg_m)
    np.testing.assert_allclose(np.linalg.norm(np.diff(plain.positions[1:, :2], axis=0), axis=1), HOLD_CFG.leg_m)
    np.testing.assert_allclose(np.diff(plain.times), HOLD_CFG.dt_s)


def test_a_predefined_holding_location_is_used_when_it_is_free():
    """Holding points (south-west 25 km, free; 19 km north, inside the cell over the goal): the
    nearer one is covered, so the plan flies to the farther one and holds there."""
    points = ((0.0, -25_000.0), (19_000.0, 0.0))
    cfg = HOLD_CFG.with_(holding_points=points, hold_speed_correction=True, max_expansions=40)
    plan = _covered_goal(cfg, est_course=-math.pi / 2)
    assert plan.status == PlanStatus.DEGRADED and plan.diagnostics["reason"] == "goal covered: holding at point 0"
    ne = plan.positions[:, :2]
    at_fix = int(np.argmin(np.linalg.norm(ne - points[0], axis=1)))
    assert np.linalg.norm(ne[at_fix] - points[0]) < 1e-6  # the plan reaches the fix ...
    assert plan.times[at_fix] == pytest.approx(25_000.0 / cfg.tas_mps, rel=0.05)
    # ... and then circles through it at V_cor: every later point within the orbit's diameter
    after = ne[at_fix:]
    assert np.linalg.norm(after - points[0], axis=1).max() <= 2 * circumradius_m(cfg) + 1e-6
    assert plan.times[-1] >= plan.times[at_fix] + cfg.replan_period_s
    # without holding points it circles where it is
    here = _covered_goal(HOLD_CFG.with_(hold_speed_correction=True), est_course=-math.pi / 2)
    assert np.linalg.norm(here.positions[:, :2], axis=1).max() <= 2 * circumradius_m(cfg) + 1e-6


@pytest.mark.parametrize(("n", "d_v"), [(4, 1.1107207), (6, 1.0471976), (8, 1.0261722)])
def test_v_cor_of_an_n_gon(n, d_v):
    """dV = S_cc / S_n = (2 pi / n) / (2 sin(pi / n)) for an n-gon of fly-over states (eq. 5.78):
    n = 4: (pi / 2) / sqrt(2) = 1.1107207; n = 6: (pi / 3) / 1 = 1.0471976; n = 8: 1.0261722.
    The HAPS at 26 m/s then holds at 28.8787, 27.2271 and 26.6805 m/s."""
    cfg = MptpConfig(course_change_max=2 * math.pi / n, hold_speed_correction=True)
    assert speed_correction(2 * math.pi / n) == pytest.approx(d_v, abs=1e-7)
    assert corrected_speed_mps(cfg) == pytest.approx(26.0 * d_v, abs=1e-5)


def test_a_hold_plan_commands_v_to_the_holding_point_and_v_cor_on_its_orbit():
    """Holding points 25 km and 12 km west (both free), the aircraft heading west at an
    estimated 28 m/s: the hold goes to the nearer point (1). The plan commands V = 26 m/s (the
    configured cruise speed, not the estimate) on every leg up to the fix, reached after
    12 km / 26 m/s = 461.5 s (+- 5 %), and V_cor = 26.680 m/s on every orbit leg after it."""
    points = ((0.0, -25_000.0), (0.0, -12_000.0))
    cfg = HOLD_CFG.with_(holding_points=points, hold_speed_correction=True, max_expansions=40)
    storm = StormSnapshot(0.0, (box(18_000, -3000, 24_000, 3000),), None)
    planner = MptpPlanner(Mission(np.array([[21_000.0, 0.0, 0.0]]), 26.0, 500.0), cfg)
    plan = planner.plan(vehicle_state(0.0, np.zeros(2), -math.pi / 2, 28.0), Threats(storms=[storm]), 0.0)
    assert plan.diagnostics["reason"] == "goal covered: holding at point 1"
    assert plan.diagnostics["tas_mps"] == 28.0  # the estimate's, for the search ...
    fix = int(np.argmin(np.linalg.norm(plan.positions[:, :2] - points[1], axis=1)))
    assert np.linalg.norm(plan.positions[fix, :2] - points[1]) < 1e-6
    assert plan.times[fix] == pytest.approx(12_000.0 / 26.0, rel=0.05)
    assert plan.airspeeds is not None  # ... but the hold is planned and commanded at the cruise V
    np.testing.assert_array_equal(plan.airspeeds[:fix], 26.0)
    np.testing.assert_allclose(plan.airspeeds[fix:], 26.0 * 1.026172, atol=1e-4)
    assert plan.diagnostics["hold_tas_mps"] == pytest.approx(26.680475, abs=1e-5)
    # the orbit's states are S_n = 26 m/s x 60 s apart, one every dt
    orbit = plan.positions[fix::ARC_POINTS, :2]
    np.testing.assert_allclose(np.linalg.norm(np.diff(orbit, axis=0), axis=1), 26.0 * 60.0)
    np.testing.assert_allclose(np.diff(plan.times[fix::ARC_POINTS]), 60.0)


def test_replans_plan_from_the_cruise_speed_while_a_hold_is_commanded():
    """While the plan in force holds at V_cor the estimate shows ~V_cor: a replan that took it as
    V would fly the next hold 2.6 % faster (V_cor of V_cor) and plan the transit after it at the
    wrong speed. The hold's replan and the first plan after it plan at the cruise 26 m/s; the
    replan after that takes the estimate again (26.3 m/s)."""
    cfg = HOLD_CFG.with_(hold_speed_correction=True)
    storm = StormSnapshot(0.0, (box(18_000, -3000, 24_000, 3000),), None)
    planner = MptpPlanner(Mission(np.array([[21_000.0, 0.0, 0.0]]), 26.0, 500.0), cfg)
    v_cor = corrected_speed_mps(cfg)
    first = planner.plan(vehicle_state(0.0, np.zeros(2), 0.0, 26.0), Threats(storms=[storm]), 0.0)
    again = planner.plan(vehicle_state(300.0, np.zeros(2), 0.0, v_cor), Threats(storms=[storm]), 300.0)
    for hold in (first, again):
        assert hold.airspeeds is not None and hold.diagnostics["hold_tas_mps"] == pytest.approx(v_cor)
    clear = [StormSnapshot(600.0, (), None)]
    after = planner.plan(vehicle_state(600.0, np.zeros(2), 0.0, v_cor), Threats(storms=clear), 600.0)
    assert after.status == PlanStatus.OK and after.airspeeds is None
    assert after.diagnostics["tas_mps"] == 26.0
    assert after.times[-1] - 600.0 == pytest.approx(21_000.0 / 26.0, rel=1e-3)
    later = planner.plan(vehicle_state(900.0, np.zeros(2), 0.0, 26.3), Threats(storms=clear), 900.0)
    assert later.diagnostics["tas_mps"] == 26.3


def test_the_follower_flies_the_plans_airspeed_per_leg_and_cruise_without_it():
    """Legs commanding 27 and 25 m/s: the demand is 27, 25, and past the plan's end still the
    last leg's 25 (its track is held until the next plan); a plan without airspeeds is flown at
    the cruise 26 m/s."""
    follower = FixedWingPlanFollower(L1Guidance(25.0, 0.75, math.radians(20.0)), 26.0, 1.0, 0.0)
    pos = np.array([[0.0, 0.0, 0.0], [1000.0, 0.0, 0.0], [2000.0, 0.0, 0.0]])
    plan = Plan(0.0, pos, np.array([0.0, 40.0, 80.0]), np.full(3, -1), airspeeds=np.array([27.0, 25.0, 99.0]))
    demands = []
    for plan_ in (plan, Plan(0.0, pos, plan.times, plan.labels)):
        follower.set_plan(plan_)
        for north in (500.0, 1500.0, 2500.0):
            sp, _ = follower.update(vehicle_state(0.0, np.array([north, 0.0]), 0.0, 26.0), 0.0, 0.1)
            demands.append(sp.tas_mps)
    assert demands == [27.0, 25.0, 25.0, 26.0, 26.0, 26.0]


# Closed loop on JSBSim with the EKF (scenarios/mptp/holding_speed.toml): the hold at V_cor from
# t = 0, the plan after it at 300 s. Tolerances: the correction is V_cor - V = 0.68 m/s, and flown
# at V instead the orbit falls 0.68 m/s x 60 s / 26.68 m/s = 1.5 s behind per state, 6.1 s at the
# last one judged (the code before the speed channel, seed 1, hold planned at the estimate's
# 27.26 m/s: 4.7, 9.1, 13.4, 17.7 s late at the states due 60-240 s). Seeds 1-20 on this code:
# TAS flown - V_cor -0.12 .. +0.12 m/s (the EKF's airspeed error per seed; TECS flies the
# estimate), vertices passed -2.3 .. +0.4 s from due (also the follower cutting the orbit's
# 400 m arcs, inside the 500 m acceptance radius), within 8.4 m (docs/mptp.md "V_cor flown").
TAS_TOL = 0.2  # |mean TAS flown - commanded| [m/s]
LAG_TOL = 3.0  # |time an orbit vertex is passed - its due time| [s]
MISS_TOL = 30.0  # closest approach to each orbit vertex [m]


def _check_hold(log) -> None:
    h = hold_flight(log, "haps")
    assert h.v_cor == pytest.approx(corrected_speed_mps(MptpConfig()))
    assert h.setpoint_max_err == 0.0  # the follower demands the plan's V_cor throughout ...
    assert abs(h.tas_mean - h.v_cor) < TAS_TOL  # ... and the aircraft flies it
    assert len(h.lag_s) >= 12
    assert np.abs(h.lag_s).max() < LAG_TOL and h.miss_m.max() < MISS_TOL
    # after the hold: planned at the cruise V (not the estimate, ~V_cor), flown at cruise again
    assert h.after_planned == 26.0 and h.cruise == 26.0
    assert abs(h.after_tas_mean - 26.0) < TAS_TOL


@pytest.mark.closed_loop
def test_the_hold_is_flown_at_v_cor_and_reaches_its_states_on_time(fly):
    _check_hold(fly("mptp/holding_speed").log)


@pytest.mark.slow
@pytest.mark.closed_loop
@pytest.mark.parametrize("seed", range(2, 21))
def test_the_hold_is_flown_at_v_cor_on_every_seed(fly, scenario_data, seed):
    data = scenario_data("mptp/holding_speed")
    data["seed"] = seed
    _check_hold(fly(data, f"holding_speed_{seed}").log)
