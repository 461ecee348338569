"""The plain-float formulations of the sensing/EKF hot path against the array algebra they
replace: the transition with a non-identity velocity map, the stacked update against the
textbook Kalman update, the sensor channels bit for bit (signed zeros included)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.core.frames import euler_to_quat, quat_exp, quat_mul, quat_normalize, quat_to_dcm
from sim.core.state import VehicleState
from sim.estimation import ins_model as m
from sim.estimation.geodetic import LocalGeodetic
from sim.estimation.ins_ekf import InsEkf, InsEkfConfig
from sim.geodesy import GeoPoint
from sim.sensors import isa
from sim.sensors.channel import Channel, ChannelConfig
from sim.sensors.measurements import BaroSample, GnssFix, MagSample

ORIGIN = GeoPoint(47.0, 8.0, 400.0)


def _nav(rng: np.random.Generator) -> m.NavState:
    return m.NavState(
        rng.normal(size=3) * 100,
        rng.normal(size=3) * 5,
        euler_to_quat(0.3, -0.2, 2.0),
        rng.normal(size=3) * 0.1,
        rng.normal(size=3) * 0.01,
        1.0,
        rng.normal(size=3),
    )


def test_transition_with_a_velocity_map_matches_finite_differences():
    """20 km east of the origin ``C`` is not the identity; the dp rows are ``C`` times the flat
    ones. Also every entry against the 3x3 array algebra (a misplaced one of the 63 written at
    once, or a wrong dt^2 term the finite differences cannot resolve, shows there)."""
    rng = np.random.default_rng(3)
    s = _nav(rng)
    c = LocalGeodetic(ORIGIN).velocity_map(5000.0, 20000.0, -300.0)
    assert np.abs(c - np.eye(3)).max() > 1e-3
    f, w, dt, decay = np.array([0.5, 0.2, -9.7]), np.array([0.1, -0.2, 0.3]), 0.01, 0.999
    nav, r, fh, wh = m.propagate(s, f, w, dt, decay, c_pos=c)
    phi = m.transition_analytic(np.eye(m.N), r, fh, wh, dt, decay, c)
    assert np.allclose(phi, m.transition_numeric(s, f, w, dt, decay, c_pos=c), atol=2e-4)
    R = np.reshape(r, (3, 3))  # the same Phi from 3x3 array algebra
    rfr = np.hstack((R @ m.skew(fh), R))
    want = np.eye(m.N)
    want[0:3, 3:6] = c * dt
    want[0:3, 6:12] = c @ rfr * -0.5 * dt * dt
    want[3:6, 6:12] = rfr * -dt
    want[3:6, 12:15] = rfr[:, 0:3] * 0.5 * dt * dt
    want[6:9, 6:9] = quat_to_dcm(quat_exp(*(np.asarray(wh) * dt))).T
    want[6:9, 12:15] = np.eye(3) * -dt
    want[16:19, 16:19] = np.eye(3) * decay
    assert np.allclose(phi, want, rtol=0, atol=1e-15)
    flat = m.propagate(s, f, w, dt, decay)[0]  # the position step is C times the flat one
    assert np.allclose(nav.p - s.p, c @ (flat.p - s.p), rtol=0, atol=1e-12)
    assert np.array_equal(nav.v, flat.v)


def test_stacked_update_is_the_kalman_update_of_the_stacked_models():
    """``fuse_batch`` (GNSS with lag, baro, magnetometer in one update) against K = P H^T S^-1
    from the array measurement models and Jacobians."""
    rng = np.random.default_rng(7)
    init = VehicleState(
        t=0.0,
        pos_ned=np.array([3000.0, 12000.0, -200.0]),
        vel_ned=np.array([8.0, -3.0, 0.5]),
        euler=np.array([0.1, -0.05, 1.2]),
        rates_body=np.zeros(3),
        alt_msl_m=600.0,
        lat_deg=0.0,
        lon_deg=0.0,
        tas_mps=0.0,
        eas_mps=0.0,
    )
    ekf = InsEkf(InsEkfConfig(), init, ORIGIN)
    for _ in range(6):  # move off the prior: correlations in P, a velocity map, an acceleration
        ekf.predict_mean([0.3, -0.2, -9.6], [0.02, 0.01, -0.03], 1 / 60, ekf.t + 1 / 60, [0.0, 0.0, 0.0])
    ekf.kf.P += np.diag(rng.uniform(0.0, 0.1, m.N))
    nav, P, t = ekf.nav.copy(), ekf.kf.P.copy(), ekf.t
    gnss = GnssFix(t - 0.11, nav.p + rng.normal(size=3), nav.v + rng.normal(size=3) * 0.1)
    baro = BaroSample(t - 0.02, isa.pressure_at_altitude(ORIGIN.alt_m - nav.p[2] + 1.5))
    mag = MagSample(t, np.array([20.0, 1.0, 41.0]))
    assert ekf.fuse_batch([gnss, baro, mag]) == 10

    c, lag, lag_b = ekf.velocity_map(), t - gnss.t, t - baro.t
    H = np.zeros((10, m.N))
    H[0:3, 0:3] = H[0:3, 16:19] = H[3:6, 3:6] = np.eye(3)
    m.H_gnss(H[0:6], lag, c)
    H[6, [2, 5, 15]] = (-1.0, lag_b, 1.0)
    field = ekf._field_ned
    m.H_mag(H[7:10], m.h_mag(nav, field))
    h = np.concatenate(
        (m.h_gnss(nav, lag, ekf._acc_ned, c), [-(nav.p[2] - nav.v[2] * lag_b) + nav.bb], m.h_mag(nav, field))
    )
    height = isa.altitude_of_pressure(baro.pressure_pa) - ORIGIN.alt_m
    z = np.concatenate((gnss.pos_ned, gnss.vel_ned, [height], mag.field_body_ut))
    std_b = ekf.cfg.baro_noise_pa * isa.height_per_pascal(baro.pressure_pa)
    R = np.diag(ekf._R_gnss_diag + [std_b**2] + ekf._R_mag_diag)
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
    dx = K @ (z - h)
    assert np.allclose(ekf.kf.P, P - K @ H @ P, rtol=0, atol=1e-12)
    assert np.allclose(ekf.nav.p, nav.p + dx[0:3], rtol=0, atol=1e-9)
    assert np.allclose(ekf.nav.v, nav.v + dx[3:6], rtol=0, atol=1e-12)
    assert np.allclose(ekf.nav.q, quat_normalize(quat_mul(nav.q, quat_exp(*dx[6:9]))), rtol=0, atol=1e-12)
    assert np.allclose(np.concatenate((ekf.nav.ba, ekf.nav.bg)), np.concatenate((nav.ba, nav.bg)) + dx[9:15])
    assert ekf.nav.bb == pytest.approx(nav.bb + dx[15], abs=1e-12)
    assert np.allclose(ekf.nav.gm, nav.gm + dx[16:19], rtol=0, atol=1e-12)


def test_float_measurement_models_match_the_array_algebra():
    s = _nav(np.random.default_rng(11))
    field = np.array([20.0, 1.0, 45.0])
    assert np.allclose(m.h_mag(s, field), field @ quat_to_dcm(s.q), rtol=0, atol=1e-12)
    c = LocalGeodetic(ORIGIN).velocity_map(-8000.0, 15000.0, 0.0)
    acc = np.array([0.3, -0.1, 0.2])
    want = np.concatenate((s.p + s.gm - c @ s.v * 0.1, s.v - acc * 0.1))
    assert np.allclose(m.h_gnss(s, 0.1, acc, c), want, rtol=0, atol=1e-12)


def _channel_reference(ch: Channel, true: np.ndarray, dt: float) -> np.ndarray:
    """The array formulation of the channel model (what ``Channel.apply`` computed before)."""
    c = ch.cfg
    if c.bias_rw > 0.0 and dt > 0.0:
        ch.bias += (c.bias_rw * math.sqrt(dt)) * ch._rng.standard_normal(ch.dim)
    y = ch.scale * true + ch.bias
    if c.noise_std > 0.0:
        y += c.noise_std * ch._rng.standard_normal(ch.dim)
    if c.quantum > 0.0:
        y = c.quantum * np.round(y / c.quantum)
    return y


@pytest.mark.parametrize(
    "cfg",
    [
        ChannelConfig(noise_std=0.3, bias_init_std=0.1, bias_rw=0.01, scale_factor_std=0.01, quantum=0.05),
        ChannelConfig(noise_std=0.001, quantum=0.25),
        ChannelConfig(noise_std=0.2),
    ],
)
@pytest.mark.parametrize("dim", [1, 3])
def test_channel_floats_give_the_array_bits(cfg: ChannelConfig, dim: int):
    """Every output bit, the sign of a zero included (a quantised negative value near zero is
    -0.0 in numpy's rounding), and the same draws from the generator."""
    a, b = Channel(cfg, dim, np.random.default_rng(1)), Channel(cfg, dim, np.random.default_rng(1))
    rng = np.random.default_rng(5)
    negative_zeros = 0
    for i in range(3000):
        true = rng.normal(size=dim) * 10.0 ** float(rng.integers(-3, 3))
        if i % 5 == 0:  # halfway between quanta: ties round to even
            true = np.round(true * 4) / 4 + 0.125
        got, want = a.apply(true, 0.01), _channel_reference(b, true, 0.01)
        assert got.tobytes() == want.tobytes(), (i, got, want)
        negative_zeros += int(np.sum((want == 0.0) & np.signbit(want)))
    assert np.array_equal(a.bias, b.bias)
    assert negative_zeros > 0 or cfg.quantum == 0.0
