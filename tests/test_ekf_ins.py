"""INS/GNSS EKF on synthetic flights with the default sensors: consistency (error within 3 sigma,
NEES), bias convergence, graceful GNSS loss and recovery, Jacobians, reproducibility."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest
from scipy.stats import chi2

from sim.core.frames import euler_to_quat, quat_conj, quat_log, quat_mul
from sim.estimation import ins_model as m
from sim.estimation.ins_ekf import InsEkf, InsEkfConfig
from sim.geodesy import GeoPoint
from sim.sensors.faults import SensorFault
from sim.sensors.suite import SensorSuite, SensorSuiteConfig
from sim.sensors.synthetic import Segment, generate

GNSS_LOSS = (60.0, 80.0)


@dataclass
class Run:
    t: np.ndarray
    err: np.ndarray  # (K, 15): pos, vel, att (body), accel bias, gyro bias; truth [-] estimate
    sig3: np.ndarray  # (K, 15)
    nees: np.ndarray  # (K,) over the 15 states
    final_bias_err: np.ndarray
    final_bias_sig3: np.ndarray


def _fly(flight, seed: int, every: int, faults=(), **ekf_overrides) -> Run:
    rng = np.random.default_rng(seed)
    cfg = SensorSuiteConfig()
    suite = SensorSuite(cfg, rng.spawn(1)[0])
    for name, f in faults:
        suite.inject(name, f)
    ecfg = InsEkfConfig.matching(cfg, **ekf_overrides)
    s0 = flight.state(0)
    s0.pos_ned = s0.pos_ned + rng.normal(0.0, ecfg.init_pos_std_m, 3)
    s0.vel_ned = s0.vel_ned + rng.normal(0.0, ecfg.init_vel_std_mps, 3)
    s0.euler = s0.euler + rng.normal(0.0, ecfg.init_tilt_std_rad, 3) * [
        1,
        1,
        ecfg.init_yaw_std_rad / ecfg.init_tilt_std_rad,
    ]
    ekf = InsEkf(ecfg, s0, flight.origin)
    imu = suite.sensors["imu"]
    ts, errs, sigs, nees = [], [], [], []
    for k in range(len(flight)):
        tr = flight.sample(k)
        ekf.push(suite.poll(tr))
        est = ekf.update(tr.t)
        if k % every:
            continue
        s = ekf.three_sigma()
        dth = quat_log(quat_mul(quat_conj(ekf.nav.q), euler_to_quat(*tr.state.euler)))
        e = np.concatenate(
            (
                tr.state.pos_ned - est.pos_ned,
                tr.state.vel_ned - est.vel_ned,
                dth,
                imu.accel.bias - ekf.nav.ba,
                imu.gyro.bias - ekf.nav.bg,
            )
        )
        ts.append(tr.t)
        errs.append(e)
        sigs.append(np.concatenate((s["pos"], s["vel"], s["att"], s["accel"], s["gyro"])))
        nees.append(float(e @ np.linalg.solve(ekf.covariance[:15, :15], e)))
    return Run(np.array(ts), np.array(errs), np.array(sigs), np.array(nees), errs[-1][9:15], sigs[-1][9:15])


@pytest.fixture(scope="module")
def multirotor() -> Run:
    """2-minute multirotor mission at 5 m/s with hovers, a turn, a climb; GNSS lost 60-80 s."""
    fl = generate(
        [
            Segment(15, 0.0),
            Segment(25, 5.0),
            Segment(20, 5.0, 0.3),
            Segment(20, 5.0, 0.0, 2.0),
            Segment(20, 5.0, -0.2, -1.0),
            Segment(20, 0.0),
        ],
        "multirotor",
        100.0,
        GeoPoint(47.0, 8.0, 400.0),
        (0.0, 0.0, -50.0),
    )
    return _fly(
        fl, seed=11, every=5, faults=[("gnss", SensorFault(kind="dropout", t_start=GNSS_LOSS[0], t_end=GNSS_LOSS[1]))]
    )


@pytest.fixture(scope="module")
def haps() -> Run:
    """10-minute HAPS flight at 18 km, 25 m/s: straight, turns (about 4 deg bank), climb, descent."""
    fl = generate(
        [
            Segment(60, 25.0),
            Segment(90, 25.0, 0.03),
            Segment(60, 25.0, 0.0, 1.0),
            Segment(90, 25.0, -0.03),
            Segment(60, 25.0, 0.0, -1.0),
            Segment(120, 25.0, 0.02),
            Segment(120, 25.0),
        ],
        "fixed_wing",
        50.0,
        GeoPoint(47.0, 8.0, 0.0),
        (0.0, 0.0, -18_000.0),
        heading_rad=1.0,
        wind_ned=(3.0, -2.0, 0.0),
    )
    return _fly(fl, seed=5, every=10)


@pytest.mark.parametrize("run", ["multirotor", "haps"])
def test_error_within_3_sigma_at_least_95_percent(run, request):
    r: Run = request.getfixturevalue(run)
    inside = (np.abs(r.err) <= r.sig3).mean(axis=0)
    assert np.all(inside >= 0.95), dict(
        zip(
            ["pn", "pe", "pd", "vn", "ve", "vd", "ax", "ay", "az", "bax", "bay", "baz", "bgx", "bgy", "bgz"],
            np.round(inside, 3),
            strict=False,
        )
    )


@pytest.mark.parametrize("run", ["multirotor", "haps"])
def test_nees_consistent(run, request):
    r: Run = request.getfixturevalue(run)
    settled = r.nees[r.t > 10.0]
    # time-averaged NEES of 15 states near its expectation 15 (not overconfident), and the
    # instantaneous NEES inside the 99 % chi-square bound most of the time
    assert settled.mean() < 2.0 * 15
    assert np.mean(settled <= chi2.ppf(0.99, 15)) > 0.9


@pytest.mark.parametrize("run", ["multirotor", "haps"])
def test_biases_converge(run, request):
    r: Run = request.getfixturevalue(run)
    # gyro biases (turn-on 0.5 deg/s = 8.7e-3 rad/s) known to < 0.05 deg/s, and within 3 sigma
    assert np.all(np.abs(r.final_bias_err[3:]) < math.radians(0.05))
    assert np.all(np.abs(r.final_bias_err) <= r.final_bias_sig3)
    # the accelerometer bias bound shrinks from its 20 mg prior (vertical axis at least 4x)
    assert r.final_bias_sig3[2] < 3 * 0.196 / 4


def test_gnss_loss_grows_position_covariance_and_recovers(multirotor):
    r = multirotor
    t0, t1 = GNSS_LOSS
    sig_h = np.hypot(r.sig3[:, 0], r.sig3[:, 1])
    before = sig_h[(r.t > t0 - 5) & (r.t <= t0)].mean()
    at_end = sig_h[(r.t > t1 - 1) & (r.t <= t1)].mean()
    after = sig_h[(r.t > t1 + 10) & (r.t <= t1 + 15)].mean()
    during = sig_h[(r.t > t0) & (r.t <= t1)]
    assert at_end > 3 * before  # grows while dead-reckoning
    assert np.all(np.diff(during) > -1e-6)  # monotonically (no position information)
    assert after < 1.5 * before  # recovers once the fix returns
    err_h = np.hypot(r.err[:, 0], r.err[:, 1])
    assert err_h[(r.t > t0) & (r.t <= t1)].max() < 15.0  # degrades gracefully
    assert err_h[(r.t > t1 + 10)].max() < 3.0


def test_analytic_jacobians_match_finite_differences():
    rng = np.random.default_rng(0)
    s = m.NavState(
        rng.normal(size=3),
        rng.normal(size=3) * 5,
        euler_to_quat(0.3, -0.2, 2.0),
        rng.normal(size=3) * 0.1,
        rng.normal(size=3) * 0.01,
        1.0,
        rng.normal(size=3),
    )
    f, w, dt, decay = np.array([0.5, 0.2, -9.7]), np.array([0.1, -0.2, 0.3]), 0.01, 0.999
    _, r, fh, wh = m.propagate(s, f, w, dt, decay)
    phi = m.transition_analytic(np.eye(m.N), r, fh, wh, dt, decay)
    assert np.allclose(phi, m.transition_numeric(s, f, w, dt, decay), atol=2e-4)  # neglected O(dt^2) terms
    field = np.array([20.0, 1.0, 45.0])
    h_mag = lambda x: m.h_mag(x, field)  # noqa: E731
    assert np.allclose(m.H_mag(np.zeros((3, m.N)), h_mag(s)), m.jacobian_numeric(h_mag, s), atol=1e-4)
    acc = np.array([0.3, -0.1, 0.2])
    h_g = lambda x: m.h_gnss(x, 0.1, acc)  # noqa: E731
    hg = np.zeros((6, m.N))
    hg[0:3, 0:3] = hg[0:3, 16:19] = hg[3:6, 3:6] = np.eye(3)
    assert np.allclose(m.H_gnss(hg, 0.1), m.jacobian_numeric(h_g, s), atol=1e-5)
    hb = np.zeros((1, m.N))
    hb[0, 2], hb[0, 15] = -1.0, 1.0
    assert np.allclose(hb, m.jacobian_numeric(m.h_baro, s), atol=1e-6)


def test_numeric_jacobian_mode_gives_the_same_estimate_and_runs_are_reproducible():
    fl = generate(
        [Segment(5, 0.0), Segment(10, 5.0, 0.2)], "multirotor", 100.0, GeoPoint(47.0, 8.0, 400.0), (0.0, 0.0, -50.0)
    )

    def final(jac, seed=3):
        suite = SensorSuite(SensorSuiteConfig(), np.random.default_rng(seed))
        ekf = InsEkf(InsEkfConfig.matching(suite.cfg, jacobians=jac), fl.state(0), fl.origin)
        for k in range(len(fl)):
            tr = fl.sample(k)
            ekf.push(suite.poll(tr))
            est = ekf.update(tr.t)
        return est, ekf.covariance.copy()

    a, pa = final("analytic")
    b, _pb = final("numeric")
    assert np.allclose(a.pos_ned, b.pos_ned, atol=0.05) and np.allclose(a.euler, b.euler, atol=2e-3)
    c, pc = final("analytic")
    assert np.array_equal(a.pos_ned, c.pos_ned) and np.array_equal(pa, pc)


def test_estimate_fields():
    fl = generate([Segment(2, 0.0)], "multirotor", 100.0, GeoPoint(47.0, 8.0, 400.0), (0.0, 0.0, -50.0))
    suite = SensorSuite(SensorSuiteConfig(), np.random.default_rng(0))
    ekf = InsEkf(InsEkfConfig.matching(suite.cfg), fl.state(0), fl.origin)
    for k in range(len(fl)):
        tr = fl.sample(k)
        ekf.push(suite.poll(tr))
        est = ekf.update(tr.t)
    truth = fl.state(len(fl) - 1)
    assert est.t == truth.t and ekf.name == "ins_ekf"
    assert est.alt_msl_m == pytest.approx(fl.origin.alt_m - est.pos_ned[2])
    assert abs(est.alt_msl_m - truth.alt_msl_m) < 10.0
    assert est.lat_deg == pytest.approx(truth.lat_deg, abs=1e-4) and est.lon_deg == pytest.approx(
        truth.lon_deg, abs=1e-4
    )
    assert est.tas_mps == pytest.approx(0.0, abs=1.5)  # pitot noise at rest (2 Pa ~ 1.8 m/s)
    assert set(ekf.three_sigma()) == {"pos", "vel", "att", "heading", "accel", "gyro", "baro"}
