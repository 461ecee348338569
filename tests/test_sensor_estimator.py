"""SensorEstimator (sensors + INS/GNSS EKF as one component) in closed loop on the JSBSim
plants, the controllers fed the estimate (never truth), through the lockstep scheduler at the
rates the world uses: consistency (errors within 3 sigma), bias convergence, a 20 s GNSS loss on
the multirotor, closed-loop speed; config errors and logging accessors."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from aircraft.haps.autopilot import HapsAutopilot, HapsGains
from aircraft.quadrotor.controller import MultirotorController
from aircraft.registry import get_airframe
from guidance.l1 import L1Guidance
from sim.core.frames import euler_to_quat, quat_conj, quat_log, quat_mul
from sim.core.setpoints import FixedWingSetpoint, MultirotorSetpoint
from sim.estimation.sensor_estimator import SensorEstimator, SensorEstimatorConfig, normal_gravity
from sim.geodesy import GeoPoint
from sim.jsbsim_plant import InitialConditions, JSBSimPlant
from sim.scheduler import LockstepScheduler, Stage
from sim.sensors.config import SensorConfigError
from sim.sensors.faults import SensorFault

ORIGIN = GeoPoint(47.0, 8.0, 0.0)
HAPS_ALT, HAPS_TAS = 18_000.0, 26.0
GNSS_LOSS = (60.0, 80.0)


class Recorder:
    """Estimate vs truth at the control rate: errors (pos, vel, body attitude, accel and gyro
    bias) and their 3-sigma bounds."""

    def __init__(self, plant: JSBSimPlant, est: SensorEstimator):
        self.plant, self.est = plant, est
        self.rows: list[np.ndarray] = []

    def __call__(self, t: float) -> None:
        tr, e = self.plant.truth(), self.est.update(t)
        ekf, imu = self.est.ekf, self.est.imu
        dth = quat_log(quat_mul(quat_conj(ekf.nav.q), euler_to_quat(*tr.euler)))
        s = ekf.three_sigma()
        self.rows.append(
            np.concatenate(
                (
                    [t],
                    tr.pos_ned - e.pos_ned,
                    tr.vel_ned - e.vel_ned,
                    dth,
                    imu.accel.bias - ekf.nav.ba,
                    imu.gyro.bias - ekf.nav.bg,
                    s["pos"],
                    s["vel"],
                    s["att"],
                    s["accel"],
                    s["gyro"],
                    tr.pos_ned,
                )
            )
        )

    def arrays(self) -> dict[str, np.ndarray]:
        a = np.array(self.rows)
        return {"t": a[:, 0], "err": a[:, 1:16], "sig3": a[:, 16:31], "pos": a[:, 31:34]}


def _inside(run, skip_s: float = 10.0) -> np.ndarray:
    """Fraction of samples within 3 sigma, per error component (after the initial transient)."""
    late = run["t"] >= skip_s
    return (np.abs(run["err"][late]) <= run["sig3"][late]).mean(axis=0)


# -- HAPS: trimmed at 18 km, straight then a 90 deg turn, autopilot + L1 on the estimate -------


def _fly_haps(seconds: float, seed: int = 3):
    af = get_airframe("haps")
    plant = JSBSimPlant(af.jsbsim_model, 1.0 / af.plant_hz, ORIGIN, af.folder)
    plant.initialise(InitialConditions(GeoPoint(ORIGIN.lat_deg, ORIGIN.lon_deg, HAPS_ALT), tas_mps=HAPS_TAS))
    plant.trim()
    cfg = SensorEstimatorConfig.for_kind(af.kind)
    cfg.check_rates(af.plant_hz)
    est = SensorEstimator(plant, cfg, np.random.default_rng(seed), ORIGIN, plant.truth())
    ap = HapsAutopilot(HapsGains.load())
    l1 = L1Guidance.for_airframe(ap)
    ap.reset(est.update(0.0), throttle=plant["fcs/throttle-cmd-norm[0]"])
    start = plant.truth().pos_ned.copy()
    leg = {"a": start, "b": start + [100_000.0, 0.0, 0.0]}
    dt = 1.0 / af.control_hz

    def control(t: float) -> None:
        e = est.update(t)
        if t >= 60.0 and leg["b"][1] == start[1]:  # turn east after a minute
            leg["a"] = e.pos_ned.copy()
            leg["b"] = e.pos_ned + [0.0, 100_000.0, 0.0]
        roll, _ = l1.update(e, leg["a"], leg["b"])
        plant.set_many(ap.update(e, FixedWingSetpoint(roll, HAPS_ALT, HAPS_TAS), dt))

    rec = Recorder(plant, est)
    sched = LockstepScheduler(af.plant_hz)
    sched.add_plant("plant", af.plant_hz, plant.step)
    sched.add_task("sense", cfg.sense_hz, Stage.SENSE, est.sense)
    sched.add_task("estimate", af.control_hz, Stage.ESTIMATE, est.update)
    sched.add_task("control", af.control_hz, Stage.CONTROL, control)
    sched.add_task("record", af.control_hz, Stage.LOG, rec)
    sched.run(round(seconds * af.plant_hz))
    return rec.arrays(), est, plant


@pytest.fixture(scope="module")
def haps():
    return _fly_haps(600.0)  # the 10-minute HAPS flight


@pytest.mark.closed_loop
def test_haps_estimate_within_3_sigma_and_flies_the_route(haps):
    run, _est, plant = haps
    frac = _inside(run)
    assert frac.min() >= 0.95, f"inside 3 sigma: {np.round(frac, 3)}"
    tr = plant.truth()
    assert abs(tr.alt_msl_m - HAPS_ALT) < 15.0  # held altitude on the estimate
    assert math.degrees(tr.course_rad) == pytest.approx(90.0, abs=3.0)  # turned onto the east leg
    late = run["t"] > 60.0
    assert np.abs(run["err"][late, 0:3]).max() < 6.0  # position [m]
    assert np.abs(run["err"][late, 3:6]).max() < 0.3  # velocity [m/s]


@pytest.mark.closed_loop
def test_haps_biases_converge(haps):
    run, est, _ = haps
    err, sig = run["err"][-1], run["sig3"][-1]
    gyro_err, gyro_sig = err[12:15], sig[12:15]
    assert np.all(np.abs(gyro_err) < gyro_sig)
    assert np.abs(gyro_err).max() < math.radians(0.05), np.degrees(gyro_err)
    assert gyro_sig.max() < math.radians(0.5) * 3 / 4  # well below the turn-on prior
    assert np.abs(err[9:12]).max() < 0.05  # accel bias [m/s^2] (turn-on 0.2)
    assert est.biases()["gyro"] == pytest.approx(list(est.ekf.nav.bg))


# -- multirotor: hover, move, 20 s GNSS loss while holding, return ---------------------------


def _quad_setpoint(t: float, home: np.ndarray) -> MultirotorSetpoint:
    if t < 20.0:
        p = home
    elif t < 100.0:
        p = home + [30.0, 20.0, -10.0]
    else:
        p = home
    return MultirotorSetpoint(pos_ned=np.array(p, float), yaw_rad=0.0 if t < 40.0 else 0.5)


def _fly_quad(seconds: float, seed: int = 5, faults=()):
    af = get_airframe("quadrotor")
    plant = JSBSimPlant(af.jsbsim_model, 1.0 / af.plant_hz, ORIGIN, af.folder)
    plant.initialise(InitialConditions(GeoPoint(ORIGIN.lat_deg, ORIGIN.lon_deg, 20.0)))
    cfg = SensorEstimatorConfig.for_kind(af.kind)
    cfg.check_rates(af.plant_hz)
    est = SensorEstimator(plant, cfg, np.random.default_rng(seed), ORIGIN, plant.truth())
    for sensor, f in faults:
        est.inject(sensor, f)
    ctrl = MultirotorController()
    ctrl.reset(est.update(0.0), landed=False)
    home = plant.truth().pos_ned.copy()
    dt = 1.0 / af.control_hz

    def control(t: float) -> None:
        plant.set_many(ctrl.update(est.update(t), _quad_setpoint(t, home), dt))

    rec = Recorder(plant, est)
    sched = LockstepScheduler(af.plant_hz)
    sched.add_plant("plant", af.plant_hz, plant.step)
    sched.add_task("sense", cfg.sense_hz, Stage.SENSE, est.sense)
    sched.add_task("estimate", af.control_hz, Stage.ESTIMATE, est.update)
    sched.add_task("control", af.control_hz, Stage.CONTROL, control)
    sched.add_task("record", 10.0, Stage.LOG, rec)
    sched.run(round(seconds * af.plant_hz))
    return rec.arrays(), est, plant, home


@pytest.fixture(scope="module")
def quad():
    return _fly_quad(120.0, faults=[("gnss", SensorFault(kind="dropout", t_start=GNSS_LOSS[0], t_end=GNSS_LOSS[1]))])


@pytest.mark.closed_loop
def test_multirotor_estimate_within_3_sigma_and_flies_the_setpoints(quad):
    run, _est, _plant, home = quad
    frac = _inside(run)
    assert frac.min() >= 0.95, f"inside 3 sigma: {np.round(frac, 3)}"
    t, pos = run["t"], run["pos"]
    at_b = (t > 50.0) & (t < GNSS_LOSS[0])
    assert np.abs(pos[at_b] - (home + [30.0, 20.0, -10.0])).max() < 1.5
    assert np.linalg.norm(pos[-1] - home) < 1.5  # back home (true position)
    assert np.abs(run["err"][t > 10.0, 12:15]).max() < math.radians(0.1)  # gyro biases


@pytest.mark.closed_loop
def test_multirotor_gnss_loss_grows_covariance_stays_controlled_and_recovers(quad):
    run, _, _, home = quad
    t, sig, pos, err = run["t"], run["sig3"], run["pos"], run["err"]
    horiz = np.hypot(sig[:, 0], sig[:, 1])
    lost = (t >= GNSS_LOSS[0] + 0.5) & (t < GNSS_LOSS[1])
    assert np.all(np.diff(horiz[lost]) >= -1e-9)  # grows monotonically without GNSS
    print(
        f"horizontal 3 sigma: {horiz[t < GNSS_LOSS[0]][-1]:.2f} m before the loss, {horiz[lost][-1]:.2f} m "
        f"at its end, {horiz[t > GNSS_LOSS[1] + 10.0][0]:.2f} m 10 s after; max true error while blind "
        f"{np.abs(err[lost, :2]).max():.2f} m"
    )
    before = horiz[(t > GNSS_LOSS[0] - 5.0) & (t < GNSS_LOSS[0])].max()
    assert horiz[lost][-1] > 2.0 * before
    # controlled: the true position stays near the held point while blind
    b = home + [30.0, 20.0, -10.0]
    assert np.abs(pos[lost] - b)[:, :2].max() < 10.0
    assert np.abs(pos[lost, 2] - b[2]).max() < 3.0
    # recovers after the loss: bound back near its value before, errors small
    after = (t > GNSS_LOSS[1] + 10.0) & (t < 100.0)
    assert horiz[after].max() < 2.0 * before
    assert np.abs(err[after, 0:3]).max() < 3.0


# -- config, accessors -------------------------------------------------------------------------


def test_config_defaults_fit_the_plant_rates():
    for name in ("haps", "quadrotor"):
        af = get_airframe(name)
        cfg = SensorEstimatorConfig.for_kind(af.kind)
        cfg.check_rates(af.plant_hz)
        assert cfg.sense_hz == af.plant_hz  # a fresh gyro sample for every inner-loop step
        assert (cfg.sense_hz / cfg.fusion_hz).is_integer()


def test_config_errors_are_clear():
    with pytest.raises(SensorConfigError, match=r"fusion_hz .* must divide the IMU rate"):
        SensorEstimatorConfig.for_kind("fixed_wing", fusion_hz=7.0)
    with pytest.raises(SensorConfigError, match="unknown airframe kind"):
        SensorEstimatorConfig.for_kind("blimp")
    with pytest.raises(SensorConfigError, match="bogus"):
        SensorEstimatorConfig.for_kind("multirotor", bogus=1)
    cfg = SensorEstimatorConfig.for_kind("fixed_wing")
    with pytest.raises(SensorConfigError, match=r"imu\.rate_hz: 120 Hz does not divide the plant rate 100 Hz"):
        cfg.check_rates(100.0)
    with pytest.raises(SensorConfigError, match=r"sensors\.imu is required"):
        SensorEstimatorConfig.build(sensors=cfg.sensors.model_copy(update={"imu": None}), fusion_hz=10.0)


def test_normal_gravity_matches_jsbsim_at_18_km():
    af = get_airframe("haps")
    plant = JSBSimPlant(af.jsbsim_model, 1.0 / af.plant_hz, ORIGIN, af.folder)
    plant.initialise(InitialConditions(GeoPoint(ORIGIN.lat_deg, ORIGIN.lon_deg, HAPS_ALT), tas_mps=HAPS_TAS))
    plant.trim()
    plant.step(5)
    from sim.core.frames import euler_to_dcm
    from sim.sensors.truth import TruthSampler

    s = TruthSampler(plant).sample()
    f_ned = euler_to_dcm(*s.state.euler) @ s.specific_force_body
    assert -f_ned[2] == pytest.approx(normal_gravity(ORIGIN.lat_deg, s.state.alt_msl_m), abs=1e-3)


def test_accessors_are_json_ready_and_runs_reproducible():
    runs = []
    for _ in range(2):
        run, est, _, _ = _fly_quad(3.0, seed=9)
        meas = est.measurements()
        assert set(meas) == {"imu", "gnss", "baro", "mag"}
        json.dumps(meas | {"sig": est.three_sigma(), "bias": est.biases()})
        assert est.measurements() == {}  # drained
        runs.append(run["err"])
    np.testing.assert_array_equal(runs[0], runs[1])
