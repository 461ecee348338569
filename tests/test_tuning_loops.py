"""Every loop of both airframes: margins from python-control against the loop's JSBSim step, and
the gain tuner (proposals flown in JSBSim, unreachable requests, low-margin warnings).

Tolerances (justified in docs/tuning.md, "Margins against JSBSim"): JSBSim overshoot within
OS_TOL_POINTS + OS_TOL_REL x linear of the linear closed loop; 2 % settling time within
TS_TOL_REL; for the loops that are an integrator plus lags near crossover (HAPS roll, quadrotor
attitude, position, yaw and altitude) the second-order overshoot from the phase margin within
SECOND_ORDER_TOL points of JSBSim.
"""

import json
import math
from dataclasses import replace

import pytest

from aircraft.haps.gains import HapsGains
from aircraft.quadrotor.gains import MultirotorGains
from sim.tuning.catalog import default_gains, file_key, gain_value, loops_of, scaled, with_gains
from sim.tuning.cli import tune_main
from sim.tuning.loops import second_order_overshoot
from sim.tuning.loops_quad import identify_rotor_axis, quad_loops
from sim.tuning.tuner import LOW_MARGIN_DEG, propose, reachable, verify_in_jsbsim

OS_TOL_POINTS, OS_TOL_REL = 2.0, 0.15
TS_TOL_REL = 0.15
SECOND_ORDER_TOL = 4.0
SECOND_ORDER_LOOPS = {("haps", "roll")} | {("quadrotor", n) for n in ("attitude", "position", "yaw", "altitude")}
QUAD_LOOPS = ("rate", "attitude", "velocity", "position", "yaw-rate", "yaw", "climb-rate", "altitude")
ALL_LOOPS = [("haps", n) for n in ("roll", "pitch", "tecs-pitch", "tecs-throttle")] + [
    ("quadrotor", n) for n in QUAD_LOOPS
]


@pytest.fixture(scope="module")
def loops():
    return {(lp.airframe, lp.name): lp for af in ("haps", "quadrotor") for lp in loops_of(af)}


def _within_tolerance(report, step) -> bool:
    """Overshoot and settling time of the JSBSim step within the tolerances of the linear ones."""
    os_ok = abs(step.overshoot_pct - report.overshoot_pct) <= OS_TOL_POINTS + OS_TOL_REL * report.overshoot_pct
    return os_ok and abs(step.settling_time_s() - report.settling_time_s) <= TS_TOL_REL * report.settling_time_s


def _agrees(report, step, pm_deg, key):
    """The JSBSim step against the linear figures (module docstring tolerances)."""
    assert math.isfinite(report.settling_time_s), "linear step must settle within the record"
    assert _within_tolerance(report, step), (report, step.overshoot_pct, step.settling_time_s())
    if key in SECOND_ORDER_LOOPS:
        assert step.overshoot_pct == pytest.approx(second_order_overshoot(pm_deg), abs=SECOND_ORDER_TOL)


@pytest.mark.parametrize("key", ALL_LOOPS, ids=lambda k: f"{k[0]}-{k[1]}")
def test_margins_of_each_loop_match_its_jsbsim_step(loops, key):
    loop = loops[key]
    g = default_gains(key[0])
    r = loop.analyse(g)
    # the shipped gains are designed with PM > 50 deg and GM > 10 dB on every loop
    assert r.phase_margin_deg > 50 and r.gain_margin_db > 10, r
    _agrees(r, loop.step(g), r.phase_margin_deg, key)


@pytest.mark.parametrize(
    ("key", "ask"),
    [
        (("haps", "roll"), {"phase_margin_deg": 65.0}),
        (("haps", "pitch"), {"crossover_rad_s": 1.5}),
        (("quadrotor", "rate"), {"phase_margin_deg": 50.0}),
        (("quadrotor", "attitude"), {"phase_margin_deg": 40.0}),
        (("quadrotor", "velocity"), {"phase_margin_deg": 60.0}),
        (("quadrotor", "position"), {"phase_margin_deg": 40.0}),
        (("quadrotor", "yaw-rate"), {"crossover_rad_s": 20.0}),
        (("quadrotor", "yaw"), {"crossover_rad_s": 5.0}),
        (("quadrotor", "climb-rate"), {"phase_margin_deg": 50.0}),
        (("quadrotor", "altitude"), {"phase_margin_deg": 45.0}),
    ],
    ids=lambda v: "-".join(v) if isinstance(v, tuple) else "-".join(f"{k}{x:g}" for k, x in v.items()),
)
def test_proposal_meets_request_and_jsbsim_agrees(loops, key, ask):
    loop = loops[key]
    g = default_gains(key[0])
    p = propose(loop, g, **ask)
    if "phase_margin_deg" in ask:
        assert p.linear.phase_margin_deg == pytest.approx(ask["phase_margin_deg"], abs=0.5)
    else:
        assert p.linear.crossover_rad_s == pytest.approx(ask["crossover_rad_s"], rel=0.01)
    assert p.factor != pytest.approx(1.0, abs=0.02)  # the request moved the gains
    assert not p.warnings
    # the proposal file's gains are the scaled shipped ones, under their gains.toml keys
    assert p.gains == {file_key(key[0], k): pytest.approx(p.factor * gain_value(g, k)) for k in loop.gains}
    verify_in_jsbsim(loop, p)
    step = loop.step(p.new_gains)
    _agrees(p.linear, step, p.linear.phase_margin_deg, key)
    assert p.jsbsim_overshoot_pct == pytest.approx(step.overshoot_pct)


def test_crossover_request_is_met(loops):
    loop = loops[("quadrotor", "attitude")]
    p = propose(loop, default_gains("quadrotor"), crossover_rad_s=5.0)
    assert p.linear.crossover_rad_s == pytest.approx(5.0, rel=0.01)


def test_unreachable_requests_name_the_loop_and_the_range(loops):
    att = loops[("quadrotor", "attitude")]
    _, w_hi, _, pm_hi = reachable(att, default_gains("quadrotor"))
    assert 15 < w_hi < 30 and pm_hi > 85  # beyond ~22 rad/s the rate loop's lag takes the margin
    with pytest.raises(
        ValueError, match=r"quadrotor attitude loop: crossover 40 rad/s unreachable; reachable: crossover"
    ):
        propose(att, default_gains("quadrotor"), crossover_rad_s=40.0)
    pitch = loops[("haps", "pitch")]
    _, _, pm_lo, _ = reachable(pitch, default_gains("haps"))
    assert pm_lo > 30
    with pytest.raises(
        ValueError, match=r"haps pitch loop: phase margin 30 deg unreachable; reachable: .* phase margin"
    ):
        propose(pitch, default_gains("haps"), phase_margin_deg=30.0)


def test_unreachable_request_cli_one_line(tmp_path, capsys):
    argv = ["gain", "quadrotor", "position", "--crossover", "50", "--no-verify", "--out", str(tmp_path)]
    assert tune_main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith("error: quadrotor position loop: crossover 50 rad/s unreachable")
    assert "reachable: crossover" in err and "rad/s" in err
    assert not list(tmp_path.iterdir())


def test_low_margin_proposal_warns_in_cli_and_file_and_overshoots_in_jsbsim(tmp_path, capsys):
    argv = ["gain", "quadrotor", "attitude", "--phase-margin", "20", "--out", str(tmp_path)]
    assert tune_main(argv) == 0
    out = capsys.readouterr().out
    assert "warning quadrotor attitude: phase margin 20.0 deg is under 30 deg" in out
    data = json.loads((tmp_path / "proposal_quadrotor_attitude.json").read_text())
    assert data["linear"]["phase_margin_deg"] == pytest.approx(20.0, abs=0.5)
    assert len(data["warnings"]) == 1 and "under 30 deg" in data["warnings"][0]
    assert data["jsbsim_overshoot_pct"] > 45  # what the warning is for (linear 57 %)
    # a margin above the threshold carries none
    assert (
        tune_main(["gain", "quadrotor", "attitude", "--phase-margin", "45", "--no-verify", "--out", str(tmp_path)]) == 0
    )
    assert "warning" not in capsys.readouterr().out
    assert json.loads((tmp_path / "proposal_quadrotor_attitude.json").read_text())["warnings"] == []
    assert LOW_MARGIN_DEG == 30.0


def test_tecs_loops_are_not_scaled_by_the_tuner(loops):
    with pytest.raises(ValueError, match=r"haps tecs-throttle loop: not tunable by one factor"):
        propose(loops[("haps", "tecs-throttle")], default_gains("haps"), phase_margin_deg=50.0)


def test_thrust_lag_matches_the_power_model():
    """Settled thrust per unit throttle against eta P_max / (V m) of gains.toml's feed-forward
    model, and an rpm lag of seconds (propeller inertia at 20 km)."""
    from sim.tuning.loops_tecs import thrust_lag
    from sim.tuning.trim_haps import jsbsim_trim

    _, plant = jsbsim_trim(20_000.0, 29.7)
    lag = thrust_lag(plant)
    g = HapsGains.load()
    assert lag.b_thr[0] == pytest.approx(g.prop_efficiency * g.power_max_w / (29.7 * g.mass_kg), rel=0.1)
    assert 1.0 < lag.tau_s < 10.0


def test_roll_gain_for_the_haps(tmp_path, capsys):
    assert tune_main(["roll-gain", "haps", "--phase-margin", "65", "--no-verify", "--out", str(tmp_path)]) == 0
    data = json.loads((tmp_path / "proposal_haps_roll.json").read_text())
    assert set(data["gains"]) == {"inner.kp_roll", "inner.ki_roll", "inner.kd_roll"}
    g = HapsGains.load()
    assert data["gains"]["inner.ki_roll"] / g.ki_roll == pytest.approx(data["gains"]["inner.kp_roll"] / g.kp_roll)
    assert data["linear"]["phase_margin_deg"] == pytest.approx(65.0, abs=0.5)


def test_gain_paths():
    g = MultirotorGains.load()
    h = with_gains(g, {"rate.roll.kd": 0.5, "position.kp_xy": 2.0})
    assert (h.rate.roll.kd, h.position.kp_xy, h.rate.roll.kp, h.rate.pitch.kd) == (
        0.5,
        2.0,
        g.rate.roll.kp,
        g.rate.pitch.kd,
    )
    s = scaled(HapsGains.load(), ("kp_pitch", "ki_pitch"), 2.0)
    assert (s.kp_pitch, s.ki_pitch, s.kd_pitch) == (8.0, 3.0, 1.0)
    assert file_key("haps", "kp_pitch") == "inner.kp_pitch" and file_key("quadrotor", "rate.roll.kp") == "rate.roll.kp"


def test_identified_roll_plant_matches_model_card():
    axis = identify_rotor_axis("roll")
    # README: 546 rad/s^2 per unit torque command, motor tau ~55 ms
    assert pytest.approx(546, rel=0.08) == axis.K
    assert 0.035 < axis.tau_s < 0.065


def test_identified_yaw_plant_leads_and_matches_model_card():
    """The reaction torque jumps with the motor current, then settles to the drag torque."""
    axis = identify_rotor_axis("yaw")
    assert pytest.approx(49, rel=0.08) == axis.K  # gains.toml: 1.23 N m = 49 rad/s^2 per unit
    assert 3.0 < axis.lead < 6.0 and 0.035 < axis.tau_s < 0.065
    assert axis.damping == 0.0


def test_identified_collective_plant_matches_the_motors_and_damps_the_climb():
    axis = identify_rotor_axis("collective")
    # four motors of 15.7 N static sea-level thrust (gains.toml) on 1.4 kg, ISA density at 100 m
    assert pytest.approx(4 * 15.7 / 1.4 * 0.9903, rel=0.05) == axis.K
    assert 0.035 < axis.tau_s < 0.065 and axis.lead == 0.0
    assert 0.05 < axis.damping < 0.3  # [1/s]: the propellers' thrust falls off with the climb speed


def test_yaw_lead_and_climb_damping_act(loops):
    """Without the identified lead (yaw) or damping (collective), the linear figures leave the
    JSBSim step's tolerance: the first-order plant of the roll axis does not describe them."""
    from sim.tuning.loops import analyse
    from sim.tuning.loops_quad import quad_vertical_loops, quad_yaw_loops

    g = MultirotorGains.load()
    yaw, collective = identify_rotor_axis("yaw"), identify_rotor_axis("collective")
    yaw_rate, altitude = loops[("quadrotor", "yaw-rate")], loops[("quadrotor", "altitude")]
    yaw_step, alt_step = yaw_rate.step(g), altitude.step(g)
    assert _within_tolerance(analyse("", *quad_yaw_loops(yaw, g)[0], yaw_rate.record_s), yaw_step)
    assert not _within_tolerance(
        analyse("", *quad_yaw_loops(replace(yaw, lead=0.0), g)[0], yaw_rate.record_s), yaw_step
    )
    assert _within_tolerance(analyse("", *quad_vertical_loops(collective, g)[1], altitude.record_s), alt_step)
    undamped = analyse("", *quad_vertical_loops(replace(collective, damping=0.0), g)[1], altitude.record_s)
    assert not _within_tolerance(undamped, alt_step)


def test_quadrotor_inner_margins_as_designed(loops):
    g = MultirotorGains.load()
    rate, att = loops[("quadrotor", "rate")].analyse(g), loops[("quadrotor", "attitude")].analyse(g)
    # model card design: rate 21.5 rad/s, 64 deg; attitude 7.0 rad/s, 63 deg, 12.6 dB
    assert rate.crossover_rad_s == pytest.approx(21.5, rel=0.1)
    assert rate.phase_margin_deg == pytest.approx(64, abs=4)
    assert att.crossover_rad_s == pytest.approx(7.0, rel=0.1)
    assert att.phase_margin_deg == pytest.approx(63, abs=4)
    assert att.gain_margin_db == pytest.approx(12.6, abs=1.5)


def test_cascade_uses_the_inner_loop_gains():
    """The velocity loop's margins change with the attitude gain beneath it (inner loop closed)."""
    axis = identify_rotor_axis("roll")
    g = MultirotorGains.load()
    soft = replace(g, attitude=replace(g.attitude, kp_roll=3.0))
    from sim.tuning.loops import analyse

    a = analyse("v", *quad_loops(axis, g).velocity, 12.0)
    b = analyse("v", *quad_loops(axis, soft).velocity, 12.0)
    assert b.phase_margin_deg < a.phase_margin_deg - 2
