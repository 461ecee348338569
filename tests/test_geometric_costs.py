"""Geometric avoider: cost terms, normalisation, sweep environment IDs and caps (spec §5, §7.1, §7.6 5–9)."""

from __future__ import annotations

import numpy as np
import pytest

from avoidance.geometric.config import CostCaps, GeometricConfig, VehicleParams
from avoidance.geometric.costs import closeness, energy, hover_power, rotation_penalty, smoothness
from avoidance.geometric.kinematics import path_kinematics
from avoidance.geometric.normalization import caps_from_samples, clip_minmax, log_clip_minmax
from sim.testbeds.geometric_sweep import (
    LOWER_CAP_ENV,
    N_ENVIRONMENTS,
    UPPER_CAP_ENV,
    env_id,
    env_index,
    env_params,
    run_sweep,
    sweep_config,
)

THESIS = CostCaps(time_lo=1.2530, time_hi=8.1436, energy_lo=249.59, energy_hi=1759.0)


def test_environment_id_formula():
    assert N_ENVIRONMENTS == 16200
    assert env_params(LOWER_CAP_ENV) == {"D_M": 3.0, "E_M": 0.0, "S_M": 1.0, "D_m": 3.0, "E_m": -10.0, "S_m": 1.0}
    assert env_params(UPPER_CAP_ENV) == {"D_M": 8.25, "E_M": -1.75, "S_M": 3.0, "D_m": 3.0, "E_m": -10.0, "S_m": 1.0}
    assert LOWER_CAP_ENV == 4 * 360 and UPPER_CAP_ENV == 3 * 3240 + 3 * 360 + 4 * 72
    for e in (0, 1, 71, 72, 3239, 16199):
        i = env_index(e)
        assert env_id(i) == e == 3240 * i[0] + 360 * i[1] + 72 * i[2] + 24 * i[3] + 3 * i[4] + i[5]
    with pytest.raises(ValueError):
        env_index(16200)


def test_energy_coefficient_and_straight_line_energy():
    veh = VehicleParams()
    assert 0.5 * veh.drag_coefficient * 1.225 * veh.effective_area == pytest.approx(0.765625)
    pts = np.linspace([0, 0, 0], [10, 0, 0], 11)[None]
    kin = path_kinematics(pts, np.array([11]), 5.0, 3.0)
    # level, constant speed: E_1 = 0; E_2 = 0.765625 · Σ|Δp| · |2v|²/2 = 0.765625 · 10 · 50
    assert energy(pts, kin.wp_vel, veh, 1.225, 9.81)[0] == pytest.approx(0.765625 * 10 * 50)
    climb = np.linspace([0, 0, 0], [0, 0, 3], 4)[None]
    kin = path_kinematics(climb, np.array([4]), 5.0, 3.0)
    assert energy(climb, kin.wp_vel, veh, 1.225, 9.81)[0] == pytest.approx(3 * 9.81 * 3 + 0.765625 * 3 * 18)


def test_hover_power_constants():
    veh, rho, g = VehicleParams(), 1.225, 9.81
    W, A = veh.mass * g, veh.n_rotors * np.pi * veh.blade_radius**2
    sigma = veh.blades_per_rotor * veh.blade_chord / (np.pi * veh.blade_radius)
    assert sigma == pytest.approx(0.11696, abs=1e-5)
    assert pytest.approx(0.45604, abs=1e-5) == A and pytest.approx(64.534, abs=1e-3) == W / A
    assert np.sqrt(W / (2 * rho * A)) == pytest.approx(5.1323, abs=1e-4)
    p0 = rho * A * veh.v_tip**3 * sigma * veh.blade_cd / 8
    hover = hover_power(np.zeros((1, 1, 3)), np.array([2]), veh, rho, g)[0]
    assert hover - p0 == pytest.approx(173.70, abs=0.05)
    lit = hover_power(np.zeros((1, 1, 3)), np.array([2]), veh, rho, g, literal_ki=True)[0]
    assert lit == pytest.approx(hover)  # V_y = 0 uses the hover formula
    # continuity at V_y = 0 of the climb and the (corrected) descent branch
    near = hover_power(np.array([[[0, 0, 1e-6]], [[0, 0, -1e-6]]]), np.array([2, 2]), veh, rho, g)
    assert np.allclose(near, hover, rtol=1e-5)


def test_normalisation_check_values():
    lim_s, lim_rp, lim_m = GeometricConfig().log_limits
    assert log_clip_minmax(1.0, *lim_s) == pytest.approx(0.5455, abs=1e-4)
    assert log_clip_minmax(1.0, *lim_rp) == pytest.approx(0.5)
    assert log_clip_minmax(1.0, *lim_m) == pytest.approx(0.99967, abs=1e-5)
    assert log_clip_minmax(np.exp(-3), *lim_m) == pytest.approx(0.0, abs=1e-12)
    assert log_clip_minmax(0.0, *lim_m) == 0.0
    assert np.allclose(
        clip_minmax(np.array([0.5, 1.253, 4.0, 9.0]), 1.253, 8.1436), [0, 0, (4 - 1.253) / (8.1436 - 1.253), 1]
    )
    caps = caps_from_samples(np.linspace(1, 11, 1001), np.linspace(100, 1100, 1001))
    assert caps.time_lo == 1 and caps.time_hi == pytest.approx(10.95 * 1.15) and caps.energy_hi == pytest.approx(1095)


def test_smoothness_and_rotation_penalty():
    x = np.linspace(0, 15, 16)
    assert smoothness(x, np.zeros((1, 16)))[0] == 0.0
    circle_x = 5 * np.cos(np.linspace(0, np.pi / 2, 200))
    circle_y = 5 * np.sin(np.linspace(0, np.pi / 2, 200))
    # curvature of a radius-5 circle is 0.2 (the integral runs over x, as in the thesis)
    k2 = smoothness(circle_x, circle_y[None])[0]
    assert k2 == pytest.approx(0.04 * (circle_x[-1] - circle_x[0]), rel=1e-2)
    assert rotation_penalty(np.array([2.0]), np.array([np.pi / 2]), 1.0)[0] == 4.0
    assert rotation_penalty(np.array([2.0]), np.array([0.0]), 1.0)[0] == 2.0


def test_closeness_terms():
    cfg = GeometricConfig()
    pts = np.array([[[0.0, 0, 0], [1, 0, 0], [2, 0, 0]]])
    samples = np.array([[[0.0, 4, 0], [2, 4, 0]]])  # nearest samples 4, √17, 4 away
    d = np.array([4, np.sqrt(17), 4]) - 1.0
    f = 1 / (0.5 * d.mean() + 0.5 * d.min())
    assert closeness(pts, np.array([3]), samples, np.array([1.0]), cfg)[0] == pytest.approx(f)
    two = np.concatenate([samples, samples + [0, 10, 0]])
    d2 = np.array([14, np.sqrt(197), 14]) - 1.0
    f2 = 1 / (0.5 * d2.mean() + 0.5 * d2.min())
    assert closeness(pts, np.array([3]), two, np.array([1.0, 1.0]), cfg)[0] == pytest.approx(
        0.5 * f + 0.5 * (f + f2) / 2
    )
    assert closeness(pts, np.array([3]), np.zeros((0, 2, 3)), np.zeros(0), cfg)[0] == 0.0


def test_default_caps_are_the_sweep_recalibration_within_spec_tolerances():
    caps = CostCaps()
    assert caps.time_hi == pytest.approx(THESIS.time_hi, rel=0.10)
    assert caps.energy_hi == pytest.approx(THESIS.energy_hi, rel=0.25)
    assert caps.time_lo == pytest.approx(THESIS.time_lo, rel=0.40)
    assert caps.energy_lo == pytest.approx(THESIS.energy_lo, rel=0.40)


def test_cap_reference_environments():
    """Lower-cap environment #1440 and upper-cap environment #11088 re-evaluated for UAV1.

    Min over #1440 is the sweep's global minimum; max time over #11088 is within the spec's ±10 %
    of the thesis upper time cap. Our energy model tops out lower than the thesis' in #11088
    (-26 %, the thesis internals are unknown, spec §2.7) — the 99.5 % sweep cap is within ±25 %."""
    veh, cfg = VehicleParams(), sweep_config()
    lo, hi = run_sweep([LOWER_CAP_ENV], cfg, veh), run_sweep([UPPER_CAP_ENV], cfg, veh)
    caps = CostCaps()
    assert lo["time"].min() == pytest.approx(caps.time_lo, abs=1e-4) == pytest.approx(THESIS.time_lo, rel=0.40)
    assert lo["energy"].min() == pytest.approx(caps.energy_lo, abs=0.01) == pytest.approx(THESIS.energy_lo, rel=0.40)
    assert hi["time"].max() == pytest.approx(THESIS.time_hi / 1.15, rel=0.10)
    assert hi["energy"].max() == pytest.approx(THESIS.energy_hi, rel=0.30)
    assert hi["time"].max() < caps.time_hi / 1.15 and hi["energy"].max() < caps.energy_hi
