"""Replay: metrics recomputed from the MCAP equal the live ones; report and A/B compare."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sim.replay.metrics import differing_keys
from sim.replay.pair_metrics import min_separation
from sim.replay.report import log_metrics, write_report
from sim.replay.runlog import RunLog
from sim.replay.trace import VehicleTrace
from sim.replay.vehicle_metrics import straight_flight_mask

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def short_run(fly_in, tmp_path_factory):
    run = fly_in(tmp_path_factory.mktemp("replay"), "haps_box_mission", "run", duration=900.0)
    return run.result, run.path


def test_replayed_metrics_equal_live_metrics(short_run):
    result, path = short_run
    replayed = log_metrics(RunLog(path))
    assert differing_keys(result.metrics, replayed) == []
    # and the live metrics stored in the log are the same numbers too
    stored = json.loads(RunLog(path).metadata["metrics"]["json"])
    assert differing_keys(stored, replayed) == []
    assert replayed["vehicles"]["haps"]["mission"]["waypoints_reached"] == 1
    assert replayed["vehicles"]["haps"]["planner_latency"]["count"] == 901  # follow_mission plans anew at every call
    assert replayed["vehicles"]["haps"]["planner_latency"]["cache_hits"] == 0


def test_report_and_compare_cli(short_run, tmp_path, cosim):
    _, path = short_run
    report, metrics = write_report(path, tmp_path / "rep")
    text = report.read_text()
    assert "vehicles.haps.tracking.altitude_error_m.max_abs" in text and "![map](map.png)" in text
    for png in ("map.png", "haps_timeseries.png"):
        assert (tmp_path / "rep" / png).stat().st_size > 10_000
    assert json.loads((tmp_path / "rep" / "metrics.json").read_text()) == json.loads(json.dumps(metrics))
    proc = cosim("compare", path, path, "--changed")
    assert proc.returncode == 0, proc.stderr
    assert "tracking" not in proc.stdout  # the same log twice: nothing changed


def _trace(name, t, pos):
    n = len(t)
    z = np.zeros(n)
    return VehicleTrace(
        name,
        "fixed_wing",
        np.asarray(t, float),
        np.asarray(pos, float),
        z,
        z,
        np.zeros((n, 3)),
        {"altitude_m": z, "tas_mps": z, "cross_track_m": z, "turning": z},
        np.zeros(0),
        0,
        [],
        truth_cross_track_m=z,
    )


def test_min_separation_matches_analytic_crossing():
    # A flies east from the origin at 10 m/s; B flies north along east = 300 m, 50 m higher
    t = np.arange(0.0, 60.0, 0.1)
    a = np.stack([np.zeros_like(t), 10 * t, np.zeros_like(t)], axis=1)
    b = np.stack([-300 + 10 * t, np.full_like(t, 300.0), np.full_like(t, -50.0)], axis=1)
    # rel = b - a = (-300 + 10t, 300 - 10t, -50): |rel| min at t = 30 s, distance 50 m
    sep = min_separation(_trace("a", t, a), _trace("b", t, b))
    assert sep["distance_m"] == pytest.approx(50.0, abs=1e-9)
    assert sep["t"] == pytest.approx(30.0)


def test_object_clearance_matches_analytic_crossing():
    """A vehicle flies east at 10 m/s; a scripted sphere (radius 5 m, appearing at 10 s) flies
    north along east = 300 m, 50 m higher: closest centre distance 50 m at t = 30 s, so 45 m to
    its surface; before it appears it is not counted."""
    from sim import scenario as sc
    from sim.geodesy import GeoPoint
    from sim.replay.metrics import MetricsWorld, run_metrics
    from sim.traffic import TrafficObject

    origin = GeoPoint(47.0, 8.0, 400.0)
    obj = TrafficObject(
        sc.TrafficObject(
            id="ball",
            radius=5.0,
            north=-200.0,
            east=300.0,
            altitude=450.0,
            velocity=sc.Velocity(north=10.0),
            appear=10.0,
        ),
        origin,
    )
    t = np.arange(0.0, 60.0, 0.1)
    a = np.stack([np.zeros_like(t), 10 * t, np.zeros_like(t)], axis=1)

    def object_metrics(tr):
        return run_metrics([tr], MetricsWorld(objects=(obj,)))["vehicles"]["a"]["clearance"]

    m = object_metrics(_trace("a", t, a))["object.ball"]
    assert m["distance_m"] == pytest.approx(45.0, abs=1e-6)
    assert m["t"] == pytest.approx(30.0)
    early = object_metrics(_trace("a", t[:50], a[:50]))["object.ball"]
    assert early["distance_m"] is None


def test_straight_flight_mask_waits_after_turns():
    t = np.arange(0, 200.0, 1.0)
    turning = (t >= 50) & (t < 60)
    m = straight_flight_mask(t, turning, settle_s=60.0)
    # straight before the first turn; not during it nor for 60 s after its last sample (t = 59 s)
    assert m[:50].all() and not m[50:119].any() and m[119:].all()


def test_planner_rerun_reproduces_recorded_decisions_and_flags_a_changed_planner(short_run):
    from avoidance.follow_mission import FollowMissionPlanner
    from sim.replay.rerun import rerun_planner

    _, path = short_run
    same = rerun_planner(path, "haps")
    assert same.plans == 901 and same.same == 901 and same.first_difference_t is None
    assert same.max_position_diff_m == 0.0 and same.max_time_diff_s == 0.0

    def slower(mission):  # another parameter set: 10 % lower cruise speed
        mission.cruise_speed *= 0.9
        return FollowMissionPlanner(mission)

    other = rerun_planner(path, "haps", slower)
    assert other.same == 0 and other.first_difference_t == 0.0
    assert other.max_time_diff_s > 60.0 and other.max_position_diff_m == 0.0
    assert "vertices differ" in other.differences[0]


def test_clearance_geofence_and_well_clear_metrics_on_a_known_geometry(fly):
    def quad(name, north):
        return {
            "name": name,
            "aircraft": "quadrotor",
            "estimator": "perfect",
            "initial": {"north": north, "altitude": 420.0},
            "mission": {
                "cruise_speed": 5.0,
                "acceptance_radius": 0.5,
                "guidance": "step",
                "waypoints": [{"north": north, "east": 0, "altitude": 420, "hold": "60 s"}],
            },
        }

    data = {
        "name": "geometry",
        "seed": 1,
        "duration": 5.0,
        "stop_when_complete": False,
        "origin": {"lat": 47.0, "lon": 8.0, "altitude": 400.0},
        "obstacle": [{"id": "mast", "shape": "cylinder", "north": 0, "east": 30, "radius": 5, "top": 410}],
        "geofence": [{"id": "site", "points": [[-200, -200], [200, -200], [200, 200], [-200, 200]], "ceiling": 500}],
        "metrics": {"well_clear_horizontal": "100 m", "well_clear_vertical": "20 m"},
        "vehicle": [quad("a", 0.0), quad("b", 60.0)],
    }
    run = fly(data, "geometry")
    m = log_metrics(run.log)
    assert differing_keys(run.result.metrics, m) == []
    a = m["vehicles"]["a"]["clearance"]
    # 25 m to the mast's side, 10 m above its top -> sqrt(25^2 + 10^2) (hover holds to ~0.1 m)
    assert a["obstacle.mast"]["distance_m"] == pytest.approx(np.hypot(25.0, 10.0), abs=0.2)
    # keep-in: 200 m to the sides, 80 m under the ceiling (500 - 420 MSL)
    assert a["geofence.site"]["margin_m"] == pytest.approx(80.0, abs=0.2) and not a["geofence.site"]["violated"]
    sep = m["separation"]["a-b"]
    assert sep["distance_m"] == pytest.approx(60.0, abs=0.2)
    assert sep["well_clear_losses"] == 1
    event = sep["well_clear_loss_events"][0]
    assert event["start"] == 0.0 and event["end"] == pytest.approx(5.0)
    assert "ap/thrust-cmd-norm" in m["vehicles"]["a"]["control_effort"]


def test_vehicles_of_different_plant_rates_share_their_log_times():
    """A 120 Hz and a 240 Hz plant log the same tick with times that differ in the last bit."""
    from types import SimpleNamespace

    from sim.replay.pair_metrics import common_times

    t240 = np.cumsum(np.full(2400, 1 / 240))[23::24]  # 0.1, 0.2, ... as accumulated 240 Hz steps
    t120 = np.cumsum(np.full(1200, 1 / 120))[11::12]
    assert np.intersect1d(t240, t120).size < t240.size  # the bits differ
    t, ia, ib = common_times(SimpleNamespace(t=t240), SimpleNamespace(t=t120))
    assert t.size == t240.size and (ia == np.arange(100)).all() and (ib == np.arange(100)).all()


@pytest.fixture(scope="module")
def quad_runs(fly_in, tmp_path_factory):
    """The square mission of the 240 Hz quadrotor flown to completion (75 s; it completes at
    70.1 s) and cut at 40 s: (live metrics of the full run, its log, the cut run's log)."""
    folder = tmp_path_factory.mktemp("quad")
    full = fly_in(folder, "quad_square_mission", "full", duration=75.0)
    cut = fly_in(folder, "quad_square_mission", "cut", duration=40.0)
    return full.result.metrics, full.path, cut.path


def test_replayed_metrics_equal_live_metrics_for_a_240_hz_quadrotor(quad_runs):
    """Mission times come from /log events, whose log times are whole nanoseconds: the live
    metrics keep them as logged (a 240 Hz tick is not a whole nanosecond)."""
    live, path, _ = quad_runs
    replayed = log_metrics(RunLog(path))
    assert differing_keys(live, replayed) == []
    mission = live["vehicles"]["quad"]["mission"]
    assert mission["complete"] and mission["waypoints_reached"] == mission["waypoints"]


def _compare_cli(*args: object) -> str:
    proc = subprocess.run(
        [sys.executable, "-m", "sim.cli", "compare", *map(str, args)],
        check=False,
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def test_compare_writes_json_and_csv_and_full_names_off_a_terminal(quad_runs, tmp_path):
    import csv

    from sim.replay.compare import compare_logs

    _, a, b = quad_runs
    rows = [r for r in compare_logs(a, b) if r[1] != r[2]]
    assert any(d not in (None, 0) for *_, d in rows)  # the runs differ in numbers
    as_json = json.loads(_compare_cli(a, b, "--changed", "--json", "-"))
    assert [[r["metric"], r["a"], r["b"], r["b_minus_a"]] for r in as_json] == json.loads(json.dumps(rows))
    _compare_cli(a, b, "--changed", "--csv", tmp_path / "ab.csv")
    with open(tmp_path / "ab.csv", newline="") as fh:
        table = list(csv.reader(fh))
    assert table[0] == ["metric", "a", "b", "b_minus_a"] and len(table) == len(rows) + 1
    for (k, x, y, d), line in zip(rows, table[1:], strict=True):
        assert line[0] == k
        for v, cell in ((x, line[1]), (y, line[2]), (d, line[3])):
            if isinstance(v, float):
                assert float(cell) == v  # exact
            elif v is None:
                assert cell == ""
    # piped (not a terminal): every metric's full name on a line of the table
    lines = _compare_cli(a, b, "--changed").splitlines()
    for k, *_ in rows:
        assert any(f"│ {k} " in line for line in lines), k


def _peak_bytes(fn) -> int:
    """Peak Python allocation [bytes] while ``fn`` runs (tracemalloc)."""
    import gc
    import tracemalloc

    gc.collect()
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_export_memory_does_not_grow_with_the_log(quad_runs, tmp_path):
    """The quadrotor's whole flight logs 1.7x the ticks of its 40 s cut (10 Hz log; both longer
    than an MCAP chunk). Exported in batches of 64 rows (both logs fill several), the peak of
    the Parquet export of its largest topics grows by less than a quarter of what reading the
    same topics whole grows by (measured: 0.4 MB, the MCAP reader's chunk, against 2.7 MB; in one
    batch, as before streaming, the export grew 2.1 MB). At CI log lengths the report's peak is
    its plotting (about 3.2 MB either way), so its streaming is shown on long logs:
    ``benchmarks/bench_replay_memory.py`` (docs/analysis.md)."""
    from sim.replay.export import export_log

    _, full, cut = quad_runs
    topics = ["/quad/truth/state", "/quad/sensors", "/quad/ctrl/commands"]
    export_log(cut, tmp_path / "warm", "parquet", topics[:1])  # imports outside the measurement
    peaks = {}
    for name, path in (("cut", cut), ("full", full)):
        peaks[name] = (
            _peak_bytes(lambda p=path, n=name: export_log(p, tmp_path / f"export_{n}", "parquet", topics, batch=64)),
            _peak_bytes(lambda p=path: RunLog(p, topics)),
        )
    (export_cut, whole_cut), (export_full, whole_full) = peaks["cut"], peaks["full"]
    assert whole_full - whole_cut > 2e6, peaks  # the whole-log reading streaming replaced
    assert export_full - export_cut < 0.25 * (whole_full - whole_cut), peaks


def test_replay_of_a_log_without_a_per_tick_topic_is_a_log_read_error(short_run, tmp_path):
    """A vehicle whose log lacks one of the per-tick topics is refused, naming the topic (not
    folded in as a vehicle without samples)."""
    from mcap.reader import make_reader
    from mcap.writer import Writer

    from sim.mcap_read import LogReadError

    _, path = short_run
    edited = tmp_path / "edited.mcap"
    with open(path, "rb") as src, open(edited, "wb") as dst:
        reader = make_reader(src)
        summary = reader.get_summary()
        assert summary is not None
        w = Writer(dst)
        w.start()
        schemas = {sid: w.register_schema(s.name, s.encoding, s.data) for sid, s in summary.schemas.items()}
        channels = {
            cid: w.register_channel(c.topic, c.message_encoding, schemas.get(c.schema_id, 0), c.metadata)
            for cid, c in summary.channels.items()
            if c.topic != "/haps/truth/tracking"
        }
        for m in reader.iter_metadata():
            w.add_metadata(m.name, m.metadata)
        for _, ch, msg in reader.iter_messages():
            if ch.id in channels:
                w.add_message(channels[ch.id], msg.log_time, msg.data, msg.publish_time)
        w.finish()
    with pytest.raises(LogReadError, match="no topic '/haps/truth/tracking'"):
        log_metrics(edited)
