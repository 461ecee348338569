"""Sensor models: statistics match their configuration, seeded reproducibility, latency, rate,
faults, config validation, ISA and the JSBSim truth sampler."""

from __future__ import annotations

import math

import numpy as np
import pytest
from shapely.geometry import Polygon, box

from sim.core.state import VehicleState
from sim.core.threats import PrismObstacle
from sim.geodesy import GeoPoint
from sim.sensors import isa
from sim.sensors.adsb import AdsbConfig, AdsbReceiver
from sim.sensors.baro import BaroConfig, Barometer
from sim.sensors.channel import Channel, ChannelConfig
from sim.sensors.config import SensorConfigError
from sim.sensors.faults import SensorFault
from sim.sensors.gnss import Gnss, GnssConfig
from sim.sensors.imu import Imu, ImuConfig
from sim.sensors.lidar import Lidar, LidarConfig, _prepare, cast_rays
from sim.sensors.suite import SensorSuite, SensorSuiteConfig
from sim.sensors.truth import TruthSample


def _truth(
    t=0.0,
    pos=(0.0, 0.0, -50.0),
    vel=(0.0, 0.0, 0.0),
    euler=(0.0, 0.0, 0.0),
    rates=(0.0, 0.0, 0.0),
    f=(0.0, 0.0, -9.80665),
    p=95_000.0,
) -> TruthSample:
    s = VehicleState(
        t=t,
        pos_ned=np.array(pos, float),
        vel_ned=np.array(vel, float),
        euler=np.array(euler, float),
        rates_body=np.array(rates, float),
        alt_msl_m=450.0,
        lat_deg=47.0,
        lon_deg=8.0,
        tas_mps=20.0,
    )
    return TruthSample(s, np.array(f, float), p, 285.0, 1.15, np.zeros(3))


def _run(sensor, n, dt, **kw):
    out = []
    for k in range(n):
        out.extend(sensor.poll(_truth(t=k * dt, **kw)))
    return out


def test_channel_noise_bias_rw_and_quantisation_statistics():
    rng = np.random.default_rng(0)
    ch = Channel(ChannelConfig(noise_std=0.3), 1, rng)
    y = np.array([ch.apply(np.zeros(1), 0.01)[0] for _ in range(20000)])
    assert abs(y.std() - 0.3) < 0.01 and abs(y.mean()) < 0.01
    # random walk: variance grows as bias_rw^2 * T over many independent channels
    chans = [Channel(ChannelConfig(bias_rw=0.2), 1, rng) for _ in range(2000)]
    for _ in range(100):
        for c in chans:
            c.apply(np.zeros(1), 0.25)
    b = np.array([c.bias[0] for c in chans])
    assert abs(b.std() / (0.2 * math.sqrt(25.0)) - 1.0) < 0.06
    q = Channel(ChannelConfig(quantum=0.5, noise_std=0.01), 1, rng)
    ys = np.array([q.apply(np.array([1.3]), 0.01)[0] for _ in range(200)])
    assert np.allclose(ys / 0.5, np.round(ys / 0.5)) and set(ys) <= {1.0, 1.5}
    s = Channel(ChannelConfig(scale_factor_std=0.01), 3, np.random.default_rng(1))
    assert np.allclose(s.apply(np.full(3, 100.0), 0.01), 100.0 * s.scale)


def test_imu_noise_matches_density_rate_and_is_reproducible():
    cfg = ImuConfig(
        rate_hz=200.0,
        accel_bias_init_std=0.0,
        accel_bias_rw=0.0,
        gyro_bias_init_std=0.0,
        gyro_bias_rw=0.0,
        accel_quantum=0.0,
        gyro_quantum=0.0,
    )
    out = _run(Imu(cfg, np.random.default_rng(3)), 4000, 0.005)
    acc = np.array([m.accel_body for m in out])
    gyr = np.array([m.gyro_body for m in out])
    assert len(out) == 4000
    assert np.allclose(acc.std(0), cfg.accel_noise_density * math.sqrt(200.0), rtol=0.05)
    assert np.allclose(gyr.std(0), cfg.gyro_noise_density * math.sqrt(200.0), rtol=0.05)
    assert np.allclose(acc.mean(0), [0, 0, -9.80665], atol=0.005)
    again = _run(Imu(cfg, np.random.default_rng(3)), 4000, 0.005)
    assert all(
        np.array_equal(a.accel_body, b.accel_body) and np.array_equal(a.gyro_body, b.gyro_body)
        for a, b in zip(out, again, strict=False)
    )


def test_rate_and_latency():
    gnss = Gnss(GnssConfig(rate_hz=5.0, latency_s=0.11), np.random.default_rng(0))
    got = []
    for k in range(1000):  # 4 s at 250 Hz
        t = k * 0.004
        got += [(t, m) for m in gnss.poll(_truth(t=t))]
    stamps = np.array([m.t for _, m in got])
    assert len(got) == 20 and np.allclose(np.diff(stamps), 0.2)
    delays = np.array([ta - m.t for ta, m in got])
    assert np.all(delays >= 0.11 - 1e-9) and np.all(delays < 0.11 + 0.004 + 1e-9)


def test_faults_bias_step_stuck_dropout():
    cfg = BaroConfig(pressure=ChannelConfig(noise_std=1.0))
    baro = Barometer(cfg, np.random.default_rng(0))
    baro.inject(SensorFault(kind="bias_step", t_start=1.0, t_end=2.0, value=500.0))
    baro.inject(SensorFault(kind="stuck", t_start=3.0, t_end=4.0))
    baro.inject(SensorFault(kind="dropout", t_start=5.0, t_end=6.0))
    out = _run(baro, 700, 0.01)
    t = np.array([m.t for m in out])
    p = np.array([m.pressure_pa for m in out])
    assert np.all(np.abs(p[t < 1.0] - 95_000) < 5) and np.all(np.abs(p[(t >= 1) & (t < 2)] - 95_500) < 5)
    stuck = p[(t >= 3) & (t < 4)]
    assert np.all(stuck == p[t < 3][-1])
    assert not np.any((t >= 5) & (t < 6)) and np.any(t >= 6)
    assert np.all(np.abs(p[t >= 6] - 95_000) < 5)


def test_gnss_loss_via_suite():
    suite = SensorSuite(SensorSuiteConfig(), np.random.default_rng(1))
    suite.inject("gnss", SensorFault(kind="dropout", t_start=2.0, t_end=4.0))
    names = []
    for k in range(600):
        names += [(type(m).__name__, m.t) for m in suite.poll(_truth(t=k * 0.01))]
    g = [t for n, t in names if n == "GnssFix"]
    assert g and not any(2.0 <= t < 4.0 for t in g) and max(g) >= 4.0
    with pytest.raises(SensorConfigError, match="no sensor 'lidar'"):
        suite.inject("lidar", SensorFault(kind="dropout", t_start=0.0))


def test_config_errors_are_clear():
    with pytest.raises(SensorConfigError, match=r"ImuConfig: rate_hz: Input should be greater than 0"):
        ImuConfig.build(rate_hz=0.0)
    with pytest.raises(SensorConfigError, match="noise_std"):
        ChannelConfig.build(noise_std=-1.0)
    with pytest.raises(SensorConfigError, match="extra_field"):
        GnssConfig.build(extra_field=1)
    with pytest.raises(SensorConfigError, match="t_end"):
        SensorFault.build(kind="stuck", t_start=5.0, t_end=1.0)
    with pytest.raises(SensorConfigError, match="bias_step needs"):
        SensorFault.build(kind="bias_step", t_start=0.0)
    imu = Imu(ImuConfig(), np.random.default_rng(0))
    with pytest.raises(SensorConfigError, match="2 axes, output has 6"):
        imu.inject(SensorFault(kind="bias_step", t_start=0.0, value=(1.0, 2.0)))


def test_suite_sensors_independent_streams_and_seeded():
    def first_gnss(cfg):
        s = SensorSuite(cfg, np.random.default_rng(7))
        for k in range(100):
            for m in s.poll(_truth(t=k * 0.01)):
                if type(m).__name__ == "GnssFix":
                    return m.pos_ned

    a = first_gnss(SensorSuiteConfig())
    assert np.array_equal(a, first_gnss(SensorSuiteConfig(imu=ImuConfig(rate_hz=50.0))))
    assert np.array_equal(a, first_gnss(SensorSuiteConfig()))


def test_isa_inverse_and_jsbsim_agreement():
    for h in (0.0, 500.0, 11_000.0, 18_000.0, 25_000.0):
        assert isa.altitude_of_pressure(isa.pressure_at_altitude(h)) == pytest.approx(h, abs=1e-6)
    jsbsim = pytest.importorskip("jsbsim")
    from sim.jsbsim_plant import InitialConditions, JSBSimPlant
    from sim.sensors.truth import TruthSampler

    plant = JSBSimPlant("c172p", 1 / 120, GeoPoint(47.0, 8.0, 0.0))
    for alt in (1000.0, 18_000.0):
        plant.initialise(InitialConditions(GeoPoint(47.0, 8.0, alt), tas_mps=50.0))
        ts = TruthSampler(plant).sample()
        assert ts.static_pressure_pa == pytest.approx(isa.pressure_at_altitude(ts.state.alt_msl_m), rel=2e-4)
        assert ts.air_temperature_k == pytest.approx(isa.temperature_at_altitude(ts.state.alt_msl_m), abs=0.05)
    assert jsbsim.__version__ == "1.3.3"


def test_truth_sampler_specific_force_in_trimmed_flight():
    pytest.importorskip("jsbsim")
    from sim.jsbsim_plant import InitialConditions, JSBSimPlant
    from sim.sensors.truth import TruthSampler

    plant = JSBSimPlant("c172p", 1 / 120, GeoPoint(47.0, 8.0, 0.0))
    plant.initialise(InitialConditions(GeoPoint(47.0, 8.0, 1000.0), tas_mps=50.0))
    plant.trim()
    plant.step(10)
    ts = TruthSampler(plant).sample()
    r_th = ts.state.euler[1]
    assert ts.specific_force_body[2] == pytest.approx(-9.80665 * math.cos(r_th), rel=0.02)
    assert abs(ts.specific_force_body[1]) < 0.05
    assert ts.dynamic_pressure_pa == pytest.approx(0.5 * ts.air_density_kgm3 * ts.state.tas_mps**2)


# -- LiDAR ---------------------------------------------------------------------------------------


def test_lidar_hits_a_box_at_the_analytic_range():
    ob = PrismObstacle("b", box(10.0, -5.0, 20.0, 5.0), up_min_m=0.0, up_max_m=30.0)
    lidar = Lidar(LidarConfig(max_range_m=50.0, range_error=ChannelConfig()), [ob], np.random.default_rng(0))
    ret = lidar.poll(_truth(pos=(0.0, 0.0, -10.0)))[0]
    d = lidar.directions
    hit = np.isfinite(ret.ranges_m)
    az = np.degrees(np.arctan2(d[:, 1], d[:, 0]))
    el = np.degrees(-np.arcsin(d[:, 2]))
    # wall at n = 10: range = 10 / (cos el cos az) where the hit point lies on the wall face
    expect = 10.0 / (np.cos(np.radians(el)) * np.cos(np.radians(az)))
    pt = expect[:, None] * d
    on_wall = (np.abs(az) < 89) & (np.abs(pt[:, 1]) <= 5.0) & (10.0 - pt[:, 2] <= 30.0) & (10.0 - pt[:, 2] >= 0.0)
    assert np.array_equal(hit, on_wall)
    assert np.allclose(ret.ranges_m[hit], expect[hit], atol=1e-9)
    ahead = np.flatnonzero((np.abs(az) < 1e-9) & (np.abs(el) < 1e-9))
    assert ret.ranges_m[ahead] == pytest.approx(10.0)


def test_lidar_top_face_holes_range_noise_and_scan_in_estimated_frame():
    ring = Polygon([(-20, -20), (20, -20), (20, 20), (-20, 20)], [[(-2, -2), (2, -2), (2, 2), (-2, 2)]])
    pr = _prepare(PrismObstacle("roof", ring, up_min_m=0.0, up_max_m=5.0))
    down = np.array([[0.0, 0.0, 1.0], [math.sqrt(0.5), 0.0, math.sqrt(0.5)]])
    r = cast_rays(np.array([0.0, 0.0, -8.0]), down, [pr], 50.0)
    assert math.isnan(r[0])  # straight down through the courtyard hole
    assert r[1] == pytest.approx(3.0 * math.sqrt(2.0))  # roof at up = 5 from up = 8, 45 deg
    ob = PrismObstacle("b", box(5.0, -50.0, 6.0, 50.0), 0.0, 100.0)
    lidar = Lidar(LidarConfig(), [ob], np.random.default_rng(2))
    ret = lidar.poll(_truth(pos=(0.0, 0.0, -10.0), euler=(0.0, 0.0, 0.0)))[0]
    ahead = np.flatnonzero(np.all(np.isclose(lidar.directions, [1.0, 0.0, 0.0], atol=1e-12), axis=1))[0]
    assert ret.ranges_m[ahead] == pytest.approx(5.0, abs=0.1)
    est = VehicleState(
        t=0.0,
        pos_ned=np.array([0.5, 0.0, -10.0]),
        vel_ned=np.zeros(3),
        euler=np.array([0.0, 0.0, 0.1]),
        rates_body=np.zeros(3),
        alt_msl_m=0.0,
        lat_deg=0.0,
        lon_deg=0.0,
    )
    scan = ret.to_scan(est)
    assert np.allclose(scan.origin_ned, est.pos_ned)
    assert scan.directions_ned[ahead] == pytest.approx([math.cos(0.1), math.sin(0.1), 0.0])
    assert scan.hit.sum() == np.isfinite(ret.ranges_m).sum() and scan.max_range_m == 10.0


def test_lidar_default_pattern_and_cost():
    d = LidarConfig().ray_directions()
    assert d.shape == (360 * 61, 3) and np.allclose(np.linalg.norm(d, axis=1), 1.0)
    assert np.degrees(np.arcsin(-d[:, 2])).max() == pytest.approx(30.0)


# -- ADS-B ---------------------------------------------------------------------------------------


def test_adsb_latency_rate_dropouts_and_quantised_altitude():
    rx = AdsbReceiver(AdsbConfig(dropout_probability=0.2), np.random.default_rng(5))
    got = []
    for k in range(6000):  # 60 s at 100 Hz, two intruders
        t = k * 0.01
        intr = {
            iid: VehicleState(
                t=t,
                pos_ned=np.array([100.0 + 10 * t, s, -300.0]),
                vel_ned=np.array([10.0, 0, 0]),
                euler=np.zeros(3),
                rates_body=np.zeros(3),
                alt_msl_m=0,
                lat_deg=0,
                lon_deg=0,
            )
            for iid, s in (("a", 0.0), ("b", 50.0))
        }
        got += [(t, r) for r in rx.poll(t, intr)]
    for iid in "ab":
        reps = [(t, r) for t, r in got if r.id == iid]
        assert 0.7 * 120 < len(reps) < 0.9 * 120  # 2 Hz x 60 s minus 20 % losses
        assert all(abs(t - r.t - 0.5) < 0.011 for t, r in reps)
        d = np.array([r.pos_ned[2] for _, r in reps])
        assert np.allclose(d / 7.62, np.round(d / 7.62))
        err = np.array([r.pos_ned[0] - (100 + 10 * r.t) for _, r in reps])
        assert abs(err.std() - 3.0) < 0.8


@pytest.mark.parametrize("fault", [None, SensorFault(kind="bias_step", t_start=1.0, value=(0, 0, 0, 0.1, 0, 0))])
def test_imu_per_sample_path_gives_the_block_path_numbers(fault):
    """``measure_one`` (the inner loops' per-sample path) equals ``measure_block`` row by row,
    across noise-pool refills (4096 rows) and with a fault active."""
    one, block = (Imu(ImuConfig(rate_hz=240.0), np.random.default_rng(1)) for _ in range(2))
    if fault is not None:
        one.inject(fault)
        block.inject(fault)
    true = np.random.default_rng(2).normal(size=(5000, 6))
    for k in range(len(true)):
        t = k / 240.0
        _, y = block.measure_block(np.array([t]), true[k : k + 1], 1.0 / 240.0)
        assert one.measure_one(t, tuple(true[k]), 1.0 / 240.0) == y[0].tolist()
    assert np.array_equal(one.gyro.bias, block.gyro.bias) and np.array_equal(one.accel.bias, block.accel.bias)
