"""MPTP holding with the speed correction V_cor and pre-defined holding locations (seed 002, 5.4),
against the thesis's numbers and hand-computed orbits."""

import math

import numpy as np
import pytest
from shapely.geometry import box

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
from sim.core.plan import PlanStatus, Threats
from sim.core.threats import StormSnapshot
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
