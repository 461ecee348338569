"""Linearisation of the HAPS: modes as on the model card, and the linear model predicts the
nonlinear JSBSim response to a small elevator doublet within 10 % over 5 s."""

import math

import control as ct
import numpy as np
import pytest

from sim.tuning.evaluator import JSBSimEvaluator
from sim.tuning.linearize import LONGITUDINAL, linearize
from sim.tuning.modes import all_modes
from sim.tuning.trim_haps import jsbsim_trim


@pytest.fixture(scope="module")
def trimmed():
    pt, plant = jsbsim_trim(20_000.0, 29.7)
    assert pt.ok
    return plant, linearize(JSBSimEvaluator(plant))


def test_modes_match_model_card(trimmed):
    _, lm = trimmed
    m = {x.name: x for x in all_modes(lm)}
    # aircraft/haps/README.md (JSBSim FGLinearization at 20 km): SP 2.94 rad/s 0.64; phugoid
    # 17.0 s; roll tau 0.27 s; Dutch roll 0.95 rad/s 0.27; spiral time to double 10.3 s
    assert m["short period"].wn_rad_s == pytest.approx(2.94, rel=0.03)
    assert m["short period"].zeta == pytest.approx(0.64, abs=0.03)
    assert m["phugoid"].period_s == pytest.approx(17.0, rel=0.03)
    assert m["phugoid"].zeta < 0.05
    assert m["roll subsidence"].time_const_s == pytest.approx(0.27, rel=0.05)
    assert m["Dutch roll"].wn_rad_s == pytest.approx(0.95, rel=0.03)
    assert m["Dutch roll"].zeta == pytest.approx(0.27, abs=0.03)
    assert m["spiral"].time_to_double_s == pytest.approx(10.3, rel=0.05)


def test_linear_model_predicts_doublet_within_10_percent(trimmed):
    plant, lm = trimmed
    amp, dt, seconds = 0.02, plant.dt, 5.0  # elevator doublet +-0.02 (0.4 deg), 1 s each way
    n = round(seconds / dt)
    t = dt * np.arange(n + 1)
    u = np.where(t < 1.0, amp, np.where(t < 2.0, -amp, 0.0))
    e0 = plant["fcs/elevator-cmd-norm"]
    x0 = JSBSimEvaluator(plant).read_state()
    i_q, i_th = 4, 7
    q_nl, th_nl = [0.0], [0.0]
    for k in range(n):
        plant["fcs/elevator-cmd-norm"] = e0 + u[k]
        plant.step()
        q_nl.append(plant["velocities/q-rad_sec"] - x0[i_q])
        th_nl.append(plant["attitude/theta-rad"] - x0[i_th])
    sys = lm.ss(LONGITUDINAL, ["fcs/elevator-cmd-norm"], ["q", "theta"])
    # JSBSim applies the command of step k over step k: zero-order hold
    resp = ct.forced_response(ct.c2d(sys, dt, "zoh"), T=t, U=u)
    for y_nl, y_lin in ((np.array(q_nl), resp.outputs[0]), (np.array(th_nl), resp.outputs[1])):
        err = np.max(np.abs(y_lin - y_nl)) / np.max(np.abs(y_nl))
        assert err < 0.10, err
    assert np.max(np.abs(th_nl)) > math.radians(0.3)  # a real response, not noise
