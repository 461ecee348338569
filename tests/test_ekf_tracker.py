"""Constant-velocity intruder tracker from ADS-B reports, through dropouts."""

from __future__ import annotations

import numpy as np
import pytest

from sim.core.state import VehicleState
from sim.estimation.intruder_tracker import IntruderTracker, TrackerConfig
from sim.sensors.adsb import AdsbConfig, AdsbReceiver
from sim.sensors.faults import SensorFault

P0 = np.array([500.0, -300.0, -120.0])
V = np.array([-12.0, 8.0, 0.5])


def _intruder(t: float) -> VehicleState:
    return VehicleState(
        t=t,
        pos_ned=P0 + V * t,
        vel_ned=V.copy(),
        euler=np.zeros(3),
        rates_body=np.zeros(3),
        alt_msl_m=0.0,
        lat_deg=0.0,
        lon_deg=0.0,
    )


def test_tracker_follows_constant_velocity_intruder_through_dropouts():
    rx = AdsbReceiver(AdsbConfig(dropout_probability=0.3, cooperative=True), np.random.default_rng(4))
    rx.inject(SensorFault(kind="dropout", t_start=30.0, t_end=40.0))  # 10 s receiver outage
    trk = IntruderTracker(TrackerConfig())
    inside, pos_err, sig_during_gap = [], [], []
    for k in range(6000):  # 60 s at 100 Hz
        t = k * 0.01
        trk.push(rx.poll(t, {"ac1": _intruder(t)}))
        if k % 50 or t < 3.0:
            continue
        (tr,) = trk.tracks(t)
        e = tr.pos_ned - _intruder(t).pos_ned
        pos_err.append(np.linalg.norm(e[:2]))
        inside.append(np.all(np.abs(e) <= 3 * np.sqrt(np.diag(tr.pos_cov))))
        if 30.5 <= t < 40.5:
            sig_during_gap.append(np.sqrt(tr.pos_cov[0, 0]))
        assert tr.cooperative and tr.id == "ac1" and tr.radius_m == 1.0
    assert np.mean(inside) >= 0.95
    assert np.max(pos_err) < 12.0 and np.median(pos_err) < 3.0
    assert sig_during_gap[-1] > 2.0 * sig_during_gap[0]  # covariance grows through the outage
    (tr,) = trk.tracks(60.0)
    assert np.all(np.abs(tr.vel_ned - V) <= 3 * np.sqrt(np.diag(tr.vel_cov)))


def test_tracks_expire_and_late_reports_are_ignored():
    from sim.sensors.measurements import AdsbReport

    trk = IntruderTracker(TrackerConfig(max_age_s=5.0))
    trk.push([AdsbReport(1.0, "x", P0.copy(), V.copy()), AdsbReport(2.0, "x", P0 + V, V.copy())])
    trk.push([AdsbReport(1.5, "x", P0 + 100.0, V.copy())])  # older than the track: ignored
    (tr,) = trk.tracks(3.0)
    assert tr.pos_ned == pytest.approx(P0 + 2 * V, abs=1.0)
    assert trk.tracks(7.5) == []
