"""Loop margins from python-control against closed-loop JSBSim step tests; gain tuner."""

import math

import pytest

from aircraft.haps.gains import HapsGains
from aircraft.quadrotor.gains import MultirotorGains
from sim.tuning.evaluator import JSBSimEvaluator
from sim.tuning.linearize import linearize
from sim.tuning.loops import (
    HapsPitchGains,
    RatePid,
    analyse,
    haps_pitch_loops,
    identify_rotor_axis,
    quad_axis_loops,
    second_order_overshoot,
)
from sim.tuning.steps import haps_pitch_step, overshoot_pct, quad_roll_step
from sim.tuning.trim_haps import jsbsim_trim
from sim.tuning.tuner import propose_roll_attitude_gain, verify_in_jsbsim


@pytest.fixture(scope="module")
def roll_axis():
    return identify_rotor_axis("roll")


def _roll_loops(axis, kp_att=None):
    g = MultirotorGains.load()
    r = g.rate.roll
    return quad_axis_loops(
        axis,
        RatePid(r.kp, r.ki, r.kd, 2 * math.pi * g.rate.d_cutoff_hz),
        kp_att if kp_att is not None else g.attitude.kp_roll,
    )


def test_identified_roll_plant_matches_model_card(roll_axis):
    # README: 546 rad/s^2 per unit torque command, motor tau ~55 ms
    assert pytest.approx(546, rel=0.08) == roll_axis.K
    assert 0.035 < roll_axis.tau_s < 0.065


def test_quadrotor_roll_margins_as_designed(roll_axis):
    l_rate, t_rate, l_att, t_att = _roll_loops(roll_axis)
    rate, att = analyse("rate", l_rate, t_rate), analyse("att", l_att, t_att)
    # model card design: rate 21.5 rad/s, 64 deg; attitude 7.0 rad/s, 63 deg, 12.6 dB
    assert rate.crossover_rad_s == pytest.approx(21.5, rel=0.1)
    assert rate.phase_margin_deg == pytest.approx(64, abs=4)
    assert att.crossover_rad_s == pytest.approx(7.0, rel=0.1)
    assert att.phase_margin_deg == pytest.approx(63, abs=4)
    assert att.gain_margin_db == pytest.approx(12.6, abs=1.5)


def test_quadrotor_roll_overshoot_consistent_with_phase_margin(roll_axis):
    """PM -> damping (second-order relation) -> overshoot, against the JSBSim roll step."""
    _, _, l_att, t_att = _roll_loops(roll_axis)
    att = analyse("att", l_att, t_att)
    _, y = quad_roll_step(step_deg=5.0)
    measured = overshoot_pct(y, math.radians(5.0))
    assert measured == pytest.approx(att.overshoot_pct, abs=2.0)  # linear closed loop
    assert measured == pytest.approx(second_order_overshoot(att.phase_margin_deg), abs=4.0)
    assert y[-1] == pytest.approx(math.radians(5.0), rel=0.02)


def test_haps_pitch_loop_matches_jsbsim_step():
    _pt, plant = jsbsim_trim(20_000.0, 29.7)
    lm = linearize(JSBSimEvaluator(plant))
    g = HapsGains.load()
    sched = g.fcs_properties()["ap/qbar-ref-psf"] / plant["aero/qbar-psf"]
    l_el, l_th, T = haps_pitch_loops(lm, HapsPitchGains(g.kp_pitch, g.ki_pitch, g.kd_pitch, sched))
    r_el, r_th = analyse("el", l_el, T), analyse("th", l_th, T)
    assert r_el.phase_margin_deg > 45 and r_el.gain_margin_db > 10
    assert r_th.phase_margin_deg > 45
    _, y = haps_pitch_step(step_deg=2.0)
    measured = overshoot_pct(y, math.radians(2.0))
    # the PI zero (not the PM) sets this overshoot: compare with the linear closed loop
    assert measured == pytest.approx(r_th.overshoot_pct, abs=2.0)


@pytest.mark.parametrize("pm", [55.0, 65.0])
def test_tuner_meets_request_and_jsbsim_agrees(roll_axis, pm):
    p = propose_roll_attitude_gain(roll_axis, phase_margin_deg=pm)
    assert p.linear.phase_margin_deg == pytest.approx(pm, abs=0.5)
    verify_in_jsbsim(p)
    # measured: PM 55 -> JSBSim 16.8 %, linear 13.3 %, 2nd order 13.0 %; PM 65 -> 0 %, 0 %, 4.7 %
    assert p.jsbsim_overshoot_pct == pytest.approx(p.linear.overshoot_pct, abs=4.0)
    assert p.jsbsim_overshoot_pct == pytest.approx(p.second_order_overshoot_pct, abs=5.0)


def test_tuner_crossover_request(roll_axis):
    p = propose_roll_attitude_gain(roll_axis, crossover_rad_s=5.0)
    assert p.linear.crossover_rad_s == pytest.approx(5.0, rel=0.01)
