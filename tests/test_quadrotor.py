"""Quadrotor airframe (JSBSim) and its PX4-style controller, flown in closed loop on truth.

The loop here is the harness's in miniature: JSBSim at 240 Hz, the Python outer loop every
4 steps (60 Hz), commands written as JSBSim properties before the next steps.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from aircraft import airframe_dir
from aircraft.quadrotor import GainsError, MultirotorController, MultirotorGains
from sim.core.setpoints import MultirotorSetpoint
from sim.geodesy import GeoPoint
from sim.jsbsim_plant import InitialConditions, JSBSimPlant

DT = 1.0 / 240.0
DIV = 4  # outer loop every 4 JSBSim steps
ORIGIN = GeoPoint(47.0, 8.0, 0.0)
MOTORS = [f"fcs/throttle-pos-norm[{i}]" for i in range(4)]


def make(
    alt_m: float = 20.0, *, on_ground: bool = False, roll: float = 0.0, pitch: float = 0.0
) -> tuple[JSBSimPlant, MultirotorController]:
    plant = JSBSimPlant("quadrotor", DT, ORIGIN, airframe_dir("quadrotor"))
    plant.initialise(
        InitialConditions(
            GeoPoint(ORIGIN.lat_deg, ORIGIN.lon_deg, alt_m), roll_rad=roll, pitch_rad=pitch, on_ground=on_ground
        )
    )
    ctrl = MultirotorController()
    ctrl.reset(plant.truth(), landed=on_ground)
    return plant, ctrl


def fly(plant: JSBSimPlant, ctrl: MultirotorController, setpoint, duration_s: float) -> dict:
    """Closed loop for ``duration_s``; ``setpoint(t)`` gives the setpoint at time t from start.

    Returns arrays sampled at the outer-loop rate: t, pos, vel, euler, motors, landed, armed.
    """
    t0 = plant.time
    keys = ("t", "pos", "vel", "euler", "motors", "landed", "armed")
    rows: dict[str, list] = {k: [] for k in keys}
    for _ in range(round(duration_s / (DIV * DT))):
        s = plant.truth()
        plant.set_many(ctrl.update(s, setpoint(s.t - t0), DIV * DT))
        plant.step(DIV)
        rows["t"].append(s.t - t0)
        rows["pos"].append(s.pos_ned)
        rows["vel"].append(s.vel_ned)
        rows["euler"].append(s.euler)
        rows["motors"].append([plant[m] for m in MOTORS])
        rows["landed"].append(ctrl.landed)
        rows["armed"].append(ctrl.armed)
    out = {k: np.array(v) for k, v in rows.items()}
    for k in ("pos", "vel", "euler", "motors"):
        assert np.isfinite(out[k]).all(), f"non-finite {k}"
    return out


def hold(sp: MultirotorSetpoint):
    return lambda t: sp


# -- gains file ------------------------------------------------------------------------------


def test_gains_load_and_convert_degrees():
    g = MultirotorGains.load()
    assert g.limits.max_tilt_rad == pytest.approx(math.radians(35.0))
    assert g.rate.roll.kp > 0.0 and g.limits.max_climb == 3.0


def test_gains_reject_unknown_and_missing_keys(tmp_path):
    text = (airframe_dir("quadrotor") / "gains.toml").read_text()
    bad = tmp_path / "typo.toml"
    bad.write_text(text.replace("kp_xy = 0.95", "kp_xyz = 0.95"))
    with pytest.raises(GainsError, match=r"\[position\]: unknown key\(s\) kp_xyz; allowed here: kp_xy, kp_z"):
        MultirotorGains.load(bad)
    nested = tmp_path / "nested.toml"
    nested.write_text(text.replace("int_lim = ", "int_limit = ", 1))  # first one: [rate.roll]
    with pytest.raises(GainsError, match=r"\[rate\] \[roll\]: unknown key\(s\) int_limit"):
        MultirotorGains.load(nested)
    missing = tmp_path / "missing.toml"
    missing.write_text(text.replace("max_climb = 3.0", ""))
    with pytest.raises(GainsError, match=r"\[limits\]: missing key\(s\) max_climb"):
        MultirotorGains.load(missing)


def test_fcs_defaults_match_gains_file():
    """The XML defaults and gains.toml agree, so the model flies the same with or without the
    controller's first command (which writes the gains)."""
    plant = JSBSimPlant("quadrotor", DT, ORIGIN, airframe_dir("quadrotor"))
    for prop, value in MultirotorGains.load().fcs_properties().items():
        assert plant[prop] == pytest.approx(value, rel=1e-5), prop


# -- model ------------------------------------------------------------------------------------


def test_ground_start_rests_on_gear():
    plant, _ = make(0.0, on_ground=True)
    z0 = plant.truth().pos_ned[2]
    plant.step(480)
    s = plant.truth()
    assert abs(s.pos_ned[2] - z0) < 0.01 and np.abs(s.vel_ned).max() < 0.01
    assert all(plant[f"gear/unit[{i}]/WOW"] == 1.0 for i in range(3))


def test_initgrnd_file_starts_on_the_ground():
    plant = JSBSimPlant("quadrotor", DT, ORIGIN, airframe_dir("quadrotor"))
    plant.fdm.load_ic("initGrnd", True)
    plant.fdm.run_ic()
    assert plant["position/h-agl-ft"] == pytest.approx(0.5, abs=1e-3)


def test_commands_reach_the_escs_in_the_same_step():
    """Flight control runs before the ESC effectors: no frame of command latency."""
    plant, _ = make()
    plant["ap/armed"] = 1.0
    plant["ap/thrust-cmd-norm"] = 0.25
    plant.step(1)
    w = plant["ap/esc-sqrt-weight"]
    expected = w * math.sqrt(0.25) + (1.0 - w) * 0.25
    assert [plant[m] for m in MOTORS] == pytest.approx([expected] * 4, abs=2e-3)


# -- closed loop ------------------------------------------------------------------------------


def test_hover_recovers_from_attitude_offsets():
    plant, ctrl = make(roll=math.radians(5.0), pitch=math.radians(5.0))
    s0 = plant.truth()
    r = fly(plant, ctrl, hold(MultirotorSetpoint(pos_ned=s0.pos_ned.copy(), yaw_rad=s0.yaw)), 8.0)
    late = r["t"] > 5.0
    assert np.abs(r["euler"][late, :2]).max() < math.radians(0.5)
    assert np.abs(r["pos"][late] - s0.pos_ned).max() < 0.05
    assert np.abs(r["pos"] - s0.pos_ned).max() < 0.5
    assert np.abs(r["vel"][late]).max() < 0.05


def test_position_step_with_yaw_change():
    plant, ctrl = make()
    p0 = plant.truth().pos_ned.copy()
    fly(plant, ctrl, hold(MultirotorSetpoint(pos_ned=p0, yaw_rad=0.0)), 1.0)
    step = np.array([10.0, 5.0, -5.0])  # 10 m N, 5 m E, 5 m up
    sp = MultirotorSetpoint(pos_ned=p0 + step, yaw_rad=math.pi / 2)
    r = fly(plant, ctrl, hold(sp), 20.0)

    dist = np.linalg.norm(step)
    progress = (r["pos"] - p0) @ (step / dist)
    assert progress.max() <= 1.2 * dist  # overshoot along the step <= 20 %
    for axis in range(3):
        along = (r["pos"][:, axis] - p0[axis]) * np.sign(step[axis])
        assert along.max() <= 1.2 * abs(step[axis]), f"axis {axis} overshoot"
    err = np.linalg.norm(r["pos"] - sp.pos_ned, axis=1)
    outside = np.nonzero(err > 0.02 * dist)[0]
    settle_s = r["t"][outside[-1] + 1] if outside.size else 0.0
    assert settle_s <= 15.0
    assert err[-1] <= 0.1
    assert abs(math.remainder(r["euler"][-1, 2] - math.pi / 2, 2 * math.pi)) < math.radians(1.0)


def test_yaw_turns_the_short_way():
    plant, ctrl = make()
    s0 = plant.truth()
    here = s0.pos_ned.copy()
    fly(plant, ctrl, hold(MultirotorSetpoint(pos_ned=here, yaw_rad=math.radians(170))), 4.0)
    r = fly(plant, ctrl, hold(MultirotorSetpoint(pos_ned=here, yaw_rad=math.radians(-170))), 3.0)
    yaw = r["euler"][:, 2]
    assert np.cos(yaw).max() < -0.9  # through south (+-180 deg), never near north
    assert abs(math.remainder(yaw[-1] - math.radians(-170), 2 * math.pi)) < math.radians(1.0)


def test_takeoff_hover_and_landing():
    plant, ctrl = make(0.0, on_ground=True)
    p0 = plant.truth().pos_ned.copy()
    g = ctrl.gains
    up = MultirotorSetpoint(pos_ned=p0 + np.array([0.0, 0.0, -10.0]))
    down = MultirotorSetpoint(pos_ned=np.array([p0[0], p0[1], np.nan]), vel_ned=np.array([0.0, 0.0, 0.7]))
    stay = MultirotorSetpoint(pos_ned=p0.copy())
    r = fly(plant, ctrl, lambda t: stay if t < 1.0 else (up if t < 13.0 else down), 32.0)

    # on the ground, disarmed, until the take-off setpoint arrives
    pre = r["t"] < 1.0
    assert r["landed"][pre].all() and not r["armed"][pre].any() and (r["motors"][pre] == 0.0).all()
    # climb limited to max_climb, reaches 10 m
    assert -r["vel"][:, 2].min() <= g.limits.max_climb + 0.3
    at_alt = (r["t"] > 10.0) & (r["t"] < 13.0)
    assert np.abs(r["pos"][at_alt, 2] - up.pos_ned[2]).max() < 0.1
    # touchdown, no bounce, land detected
    height = p0[2] - r["pos"][:, 2]
    touch = np.nonzero((r["t"] > 13.0) & (height < 0.02))[0][0]
    assert height[touch:].max() < 0.3
    landed = np.nonzero(r["landed"] & (r["t"] > 13.0))[0][0]
    assert r["t"][landed] - r["t"][touch] < 1.5
    # motors at idle once landed, stopped after the disarm delay
    w = plant["ap/esc-sqrt-weight"]
    f_idle = g.mixer.idle_thrust
    idle = w * math.sqrt(f_idle) + (1.0 - w) * f_idle
    t_land = r["t"][landed]
    idle_phase = (r["t"] > t_land + 0.1) & (r["t"] < t_land + g.land.disarm_delay_s - 0.1)
    assert np.abs(r["motors"][idle_phase] - idle).max() < 0.01
    stopped = r["t"] > t_land + g.land.disarm_delay_s + 0.1
    assert stopped.any() and (r["motors"][stopped] == 0.0).all() and not r["armed"][stopped].any()
