"""Streaming metrics: memory does not grow with the run's duration, and the chunked reductions
give the numbers the whole series gives."""

import gc
import math
import tracemalloc

import numpy as np
import pytest
import shapely

from sim.core.state import VehicleState
from sim.core.threats import PrismObstacle
from sim.replay.metrics import MetricsWorld, RunMetrics, run_metrics
from sim.replay.reducers import LATENCY_EXACT, Intervals, LatencySketch, RunningStats
from sim.replay.trace import CHUNK, TraceRecorder

LOG_HZ = 10.0


def _fly(ticks: int) -> RunMetrics:
    """Two synthetic vehicles logged for ``ticks`` log ticks through the live recorders into
    one RunMetrics (with an obstacle; a planner call per tick)."""
    acc = RunMetrics(MetricsWorld(obstacles=(_mast(),), well_clear_h_m=50.0, well_clear_v_m=10.0))
    for name in ("a", "b"):
        acc.vehicle(name, "fixed_wing")
    _feed(ticks, acc.add)
    return acc


def _feed(ticks: int, sink, chunk: int = CHUNK) -> None:
    """Vehicle a flies east at 25 m/s weaving 1 m; b 30 m to its side; turns for 3 s every 2 min."""
    recorders = [
        (TraceRecorder(name, "fixed_wing", 4, sink=sink, chunk=chunk), east) for name, east in (("a", 0.0), ("b", 30.0))
    ]
    sigma = {"pos": [3.0, 3.0, 5.0], "vel": [0.3, 0.3, 0.5]}
    for k in range(ticks):
        t = k / LOG_HZ
        for rec, east in recorders:
            pos = [25.0 * t, east + math.sin(0.01 * k), -100.0]
            state = VehicleState(
                t=t,
                pos_ned=np.array(pos),
                vel_ned=np.array([25.0, 0.0, 0.0]),
                euler=np.array([0.1 * math.sin(0.02 * k), 0.05, 0.0]),
                rates_body=np.zeros(3),
                alt_msl_m=100.0,
                lat_deg=0.0,
                lon_deg=0.0,
                tas_mps=25.0,
            )
            setpoint = {"altitude_m": 100.5, "cross_track_m": 0.0, "turning": k % 1200 < 30, "tas_mps": 25.0}
            rec.state(state, setpoint, {"ap/roll-cmd-rad": 0.01, "fcs/throttle-cmd-norm[0]": 0.8}, 0.5)
            estimate = VehicleState(
                t, np.array(pos), np.array([25.0, 0.1, 0.0]), state.euler, state.rates_body, 100.0, 0.0, 0.0
            )
            rec.estimate(estimate, sigma)
            rec.latency(1e-3 * (1 + k % 7))
    for rec, _ in recorders:
        rec.flush()


def _mast() -> PrismObstacle:
    return PrismObstacle(id="mast", footprint=shapely.Point(0.0, 200.0).buffer(5.0), up_min_m=0.0, up_max_m=50.0)


def _peak_bytes(ticks: int) -> int:
    gc.collect()
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        acc = _fly(ticks)
        size = tracemalloc.get_traced_memory()[1] - base  # the peak while flying
    finally:
        tracemalloc.stop()
    assert acc.result()["vehicles"]["a"]["tracking"]["cross_track_m"]["count"] > 0
    return size


def test_metrics_memory_does_not_grow_with_duration():
    """Peak memory of the live metrics of two vehicles over N and over 10 N log ticks
    (N = 6000, past the exact-latency limit): the same within 64 kB (both about 2.2 MB, a
    chunk's arrays). Recorders that keep every tick (the old live metrics; here a chunk longer
    than the run) peak at 11.7 and 115 MB."""
    n = 6_000
    assert n > LATENCY_EXACT  # the latency sketch has switched to its histogram
    small, large = _peak_bytes(n), _peak_bytes(10 * n)
    assert large - small < 64_000, (small, large)


def test_chunked_metrics_equal_whole_series_numbers():
    """The streamed tracking, path and separation figures against numpy over the whole series."""
    ticks = 5_000
    m = _fly(ticks).result()
    t = np.arange(ticks) / LOG_HZ
    turning = np.arange(ticks) % 1200 < 30
    last_turn = np.maximum.accumulate(np.where(turning, t, -np.inf))
    settled = ~turning & (t - last_turn >= 60.0)
    alt = m["vehicles"]["a"]["tracking"]["altitude_error_m"]
    assert alt["count"] == settled.sum() and alt["mean"] == pytest.approx(-0.5) and alt["max_abs"] == 0.5
    east = np.sin(0.01 * np.arange(ticks))
    path = np.linalg.norm(np.diff(np.stack([25.0 * t, east], axis=1), axis=0), axis=1).sum()
    assert m["vehicles"]["a"]["mission"]["path_length_m"] == pytest.approx(path, rel=1e-12)
    bank = np.degrees(np.max(np.abs(0.1 * np.sin(0.02 * np.arange(ticks)))))
    assert m["vehicles"]["a"]["tracking"]["max_bank_deg"] == pytest.approx(bank)
    sep = m["separation"]["a-b"]
    assert sep["distance_m"] == 30.0 and sep["t"] == 0.0 and sep["well_clear_losses"] == 1
    assert sep["well_clear_loss_events"] == [{"start": 0.0, "end": t[-1], "min_distance_m": 30.0}]
    lat = m["vehicles"]["a"]["planner_latency"]
    exact = 1e-3 * (1 + np.arange(ticks) % 7)
    assert lat["count"] == ticks and lat["max_ms"] == pytest.approx(7.0)
    assert lat["median_ms"] == pytest.approx(np.median(exact) * 1e3, rel=0.005)
    assert lat["p95_ms"] == pytest.approx(np.percentile(exact, 95) * 1e3, rel=0.005)
    mast = m["vehicles"]["a"]["clearance"]["obstacle.mast"]
    assert mast["distance_m"] == pytest.approx(np.hypot(195.0, 50.0), abs=0.2)


def test_intervals_are_the_same_however_the_samples_are_cut():
    rng = np.random.default_rng(3)
    t = np.arange(500.0)
    inside = rng.random(500) < 0.6
    dist = rng.random(500)
    whole = Intervals()
    whole.add(t, inside, dist)
    for cut in (1, 2, 7, 64):
        parts = Intervals()
        for s in range(0, 500, cut):
            parts.add(t[s : s + cut], inside[s : s + cut], dist[s : s + cut])
        assert parts.result() == whole.result()


def test_latency_sketch_is_exact_then_within_its_bin_width():
    rng = np.random.default_rng(5)
    x = rng.lognormal(-4.0, 1.5, 50_000)
    sketch = LatencySketch()
    sketch.add(x[:LATENCY_EXACT])
    assert sketch.quantile(0.5) == np.median(x[:LATENCY_EXACT])  # exact while it can keep them
    for s in range(LATENCY_EXACT, x.size, 1000):
        sketch.add(x[s : s + 1000])
    for q in (0.5, 0.95):
        assert sketch.quantile(q) == pytest.approx(np.quantile(x, q), rel=0.006)
    assert sketch.max_s == x.max() and sketch.count == x.size


def test_running_stats_equal_numpy():
    x = np.random.default_rng(1).normal(2.0, 3.0, 10_000)
    rs = RunningStats()
    for s in range(0, x.size, 1024):
        rs.add(x[s : s + 1024])
    r = rs.result()
    assert r["mean"] == pytest.approx(x.mean(), rel=1e-12)
    assert r["rms"] == pytest.approx(np.sqrt(np.mean(x * x)), rel=1e-12)
    assert r["max_abs"] == np.abs(x).max() and r["count"] == x.size


def test_replay_cuts_the_chunks_the_live_run_folds_in():
    """run_metrics on the whole traces (the replay path) equals the live recorders' result."""
    ticks = 3 * CHUNK + 17
    live = _fly(ticks)
    whole: dict = {}
    _feed(ticks, lambda tr: whole.setdefault(tr.name, tr), chunk=10**9)
    assert len(whole["a"].t) == ticks
    assert run_metrics([whole["a"], whole["b"]], live.world) == live.result()
