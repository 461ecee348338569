"""The Monte-Carlo study of seed 002 6.2: storm-field generator, trial draws, one hand-built trial,
statistics, and a four-trial study through the process pool (benchmarks/bench_mptp_montecarlo.py
runs the full one)."""

from __future__ import annotations

import json
import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace

import numpy as np
import pytest
from scipy import optimize, stats
from shapely.geometry import Polygon, box

from guidance.mptp.search import plan_trajectory
from guidance.mptp.timeline import ObstacleTimeline
from sim.testbeds import mptp_mc_stats as mcs
from sim.testbeds import mptp_montecarlo as mc
from sim.testbeds.mptp_mc_fields import Cells, FieldSpec, coverage, draw_cells, nowcast

BOUNDS = (0.0, 0.0, 280_000.0, 280_000.0)


def _ks_uniform(x: np.ndarray, lo: float, hi: float) -> float:
    return float(stats.kstest(x, "uniform", args=(lo, hi - lo)).pvalue)


def test_generated_cells_follow_the_stated_distribution():
    spec = FieldSpec(bounds=BOUNDS, n_cells=3000, pad_m=20_000.0)
    cells = draw_cells(spec, 5)
    assert cells.outlines.shape == (3000, spec.n_vertices, 2)
    assert cells.speeds.min() >= 6.2 - 1e-9 and cells.speeds.max() <= 17.6 + 1e-9
    assert cells.courses_deg.min() >= 88.5 - 1e-9 and cells.courses_deg.max() <= 128.5 + 1e-9
    assert _ks_uniform(cells.speeds, 6.2, 17.6) > 0.01
    assert _ks_uniform(cells.courses_deg, 88.5, 128.5) > 0.01
    # centres uniform over the bounds widened by the pad (the outline's mean is the centre up to
    # the harmonics' small offset)
    c = cells.centres
    assert _ks_uniform(c[:, 0], -20_000.0, 300_000.0) > 0.01
    assert _ks_uniform(c[:, 1], -20_000.0, 300_000.0) > 0.01
    # the largest radius of an outline is its semi-major axis within the roughness
    r = np.linalg.norm(cells.outlines - c[:, None, :], axis=2).max(axis=1)
    assert r.min() > 0.6 * spec.radius_m[0] and r.max() < 1.5 * spec.radius_m[1]
    assert np.median(r) == pytest.approx(np.mean(spec.radius_m), rel=0.15)


def test_fields_are_seeded_and_independent():
    spec = FieldSpec(bounds=BOUNDS)
    a, b, c = draw_cells(spec, 3), draw_cells(spec, 3), draw_cells(spec, 4)
    assert np.array_equal(a.outlines, b.outlines) and np.array_equal(a.velocities, b.velocities)
    assert not np.allclose(a.velocities, c.velocities)


@pytest.mark.parametrize(
    "change",
    [
        {"n_cells": 5},
        {"radius_m": (1_000.0, 2_000.0)},
        {"aspect": (0.9, 1.0)},
        {"speed_mps": (1.0, 2.0)},
        {"course_deg": (0.0, 10.0)},
        {"pad_m": 0.0},
        {"roughness": 0.0},
        {"n_vertices": 12},
        {"bounds": (0.0, 0.0, 100_000.0, 100_000.0)},
    ],
)
def test_every_field_spec_input_changes_the_field(change):
    base = FieldSpec(bounds=BOUNDS)
    a, b = draw_cells(base, 1), draw_cells(replace(base, **change), 1)
    same = a.outlines.shape == b.outlines.shape and np.allclose(a.outlines, b.outlines)
    assert not (same and np.allclose(a.velocities, b.velocities))


def test_nowcast_moves_every_cell_with_its_velocity():
    cells = draw_cells(FieldSpec(bounds=BOUNDS, n_cells=6), 2)
    snaps = nowcast(cells, t_issue=100.0, horizon_s=3600.0, step_s=300.0)
    assert [s.t for s in snaps] == [100.0 + 300.0 * k for k in range(13)]
    c0 = np.array([p.centroid.coords[0] for p in snaps[0].cells])
    c12 = np.array([p.centroid.coords[0] for p in snaps[12].cells])
    assert np.allclose(c12 - c0, cells.velocities * 3600.0, atol=1e-6)


def test_coverage_of_a_hand_built_cell():
    square = np.array([[[0.0, 0.0], [10_000.0, 0.0], [10_000.0, 10_000.0], [0.0, 10_000.0]]])
    cells = Cells(square + 50_000.0, np.array([[0.0, 10.0]]))
    area = box(0.0, 0.0, 200_000.0, 200_000.0)
    grown = 10_000.0**2 + 4 * 10_000.0 * 5_000.0 + math.pi * 5_000.0**2  # square + sides + corners
    # the buffer's corners are 32-gons inscribed in the quarter circles
    assert coverage(cells, area, 5_000.0, 0.0) == pytest.approx(grown / area.area, rel=2e-3)
    cells_out = Cells(square + np.array([50_000.0, 190_000.0]), np.array([[0.0, 10.0]]))
    # moved 36 km east in an hour: only the 5 km left of the border (x 185-200 km) remains, now gone
    assert coverage(cells_out, area, 5_000.0, 3600.0) == 0.0
    assert coverage(cells_out, area, 5_000.0, 0.0) > 0.0


def test_study_fields_cover_about_the_thesis_share_of_the_mission_area():
    area, spec = mc.mission_area(), mc.study_field_spec()
    issue = np.mean([coverage(draw_cells(spec, s), area, 10_000.0, 0.0) for s in range(40)])
    hour = np.mean([coverage(draw_cells(spec, s), area, 20_000.0, 3600.0) for s in range(40)])
    # thesis 6.2: 18.2 % at issue, 26.4 % after one hour (here 19.1 % and 31.1 %: see docs/mptp.md)
    assert 0.16 < issue < 0.22 and 0.26 < hour < 0.34


def test_study_config_has_the_thesis_margins():
    cfg = mc.study_config("edh")
    assert (cfg.dt_s, cfg.tas_mps, cfg.max_expansions, cfg.turning) == (50.0, 80.0, 100, "both")
    assert math.degrees(cfg.course_change_max) == pytest.approx(45.0)
    k = math.sqrt(-2 * math.log(1 - cfg.probability))
    assert k * cfg.sigma_front_mps * 3600.0 == pytest.approx(10_000.0)
    assert cfg.safety_single_m == (10_000.0,) * 3


@pytest.fixture(scope="module")
def field0():
    cfg = mc.study_config("ssph")
    cells = draw_cells(mc.study_field_spec(), 0)
    return cfg, ObstacleTimeline(nowcast(cells), cfg, 2 * mc.HORIZON_S)


def test_drawn_trials_meet_the_thesis_conditions(field0):
    cfg, tl = field0
    trials = mc.draw_trials(tl, cfg, 0, 6, seed=9)
    assert [t.index for t in trials] == list(range(6))
    assert trials == mc.draw_trials(tl, cfg, 0, 6, seed=9)
    inner = cfg.mission_area.buffer(-mc.BORDER_M)
    levels = np.arange(int(tl.interval(mc.HORIZON_S)) + 1)
    envs = tl.envelopes(levels, levels + 1)
    for t in trials:
        for p in (t.start, t.goal):
            assert inner.contains(Polygon([p, (p[0] + 1, p[1]), (p[0], p[1] + 1)]))
            assert not any(e.intersects(Polygon([p, (p[0] + 1, p[1]), (p[0], p[1] + 1)])) for e in envs)
        assert 0.3 * 288_000.0 <= t.static_path_m <= 0.8 * 288_000.0
        assert t.static_path_m >= math.dist(t.start, t.goal) - 1e-6
        to_goal = round(math.degrees(math.atan2(t.goal[1] - t.start[1], t.goal[0] - t.start[0]))) % 360
        assert t.course_deg != to_goal and 0 <= t.course_deg <= 359


def _hand_arrival(p0: np.ndarray, course: float, goal: np.ndarray, radius: float, speed: float) -> float:
    """A right turn at ``radius`` from p0 until the goal is dead ahead, then straight [s]."""

    def e(chi: float) -> np.ndarray:
        return np.array([math.cos(chi), math.sin(chi)])

    centre = p0 + radius * e(course + math.pi / 2)

    def off_ray(th: float) -> float:
        at = centre + radius * e(course - math.pi / 2 + th)
        h, d = e(course + th), goal - at
        return h[0] * d[1] - h[1] * d[0]

    th = optimize.brentq(off_ray, 1e-6, math.pi / 2)
    at = centre + radius * e(course - math.pi / 2 + th)
    return (radius * th + float(np.linalg.norm(goal - at))) / speed


@pytest.mark.parametrize("heuristic", mc.HEURISTICS)
def test_a_trial_without_storms_turns_once_and_flies_straight_to_the_goal(heuristic):
    cfg = mc.study_config(heuristic)
    tl = ObstacleTimeline(nowcast(Cells(np.empty((0, 24, 2)), np.empty((0, 2)))), cfg, 2 * mc.HORIZON_S)
    start = np.array([100_000.0, 100_000.0])
    goal = start + 120_000.0 * np.array([math.cos(math.radians(30.0)), math.sin(math.radians(30.0))])
    trial = mc.Trial(0, 0, tuple(start), tuple(goal), 0, float(np.linalg.norm(goal - start)))
    row = mc.run_trial(tl, trial, cfg)
    assert row["success"] and row["trst"] == 1 and row["exst"] == 1
    assert row["length_m"] == pytest.approx(120_000.0)
    assert row["arrival_s"] == pytest.approx(_hand_arrival(start, 0.0, goal, cfg.turn_radius_m, 80.0), abs=1e-6)
    assert row["runtime_s"] > 0.0


def test_a_goal_walled_in_for_the_hour_is_a_failure_within_the_cap():
    cfg = mc.study_config("edh")
    ring = np.array([[math.cos(a), math.sin(a)] for a in np.linspace(0, 2 * math.pi, 24, endpoint=False)])
    cells = Cells((160_000.0 + 30_000.0 * ring)[None], np.zeros((1, 2)))  # a still 30 km cell
    tl = ObstacleTimeline(nowcast(cells), cfg, 2 * mc.HORIZON_S)
    goal = np.array([160_000.0, 160_000.0 + 35_000.0])  # outside the cell, inside its >= 10 km margin
    trial = mc.Trial(0, 0, (60_000.0, 60_000.0), tuple(goal), 90, 0.0)
    row = mc.run_trial(tl, trial, cfg)
    assert not row["success"] and row["exst"] <= mc.MAX_EXPANSIONS and math.isnan(row["length_m"])


def test_a_planner_exception_is_a_failed_trial_with_its_message(monkeypatch, field0):
    cfg, tl = field0

    def crash(*args, **kwargs):
        raise AttributeError("'NoneType' object has no attribute 'distance'")

    monkeypatch.setattr(mc, "plan_trajectory", crash)
    trial = mc.Trial(0, 0, (100_000.0, 100_000.0), (150_000.0, 150_000.0), 0, 0.0)
    row = mc.run_trial(tl, trial, cfg)
    assert (
        not row["success"] and row["status"] == "error: AttributeError: 'NoneType' object has no attribute 'distance'"
    )
    summary = mcs.summarise([{**row, "field": 0, "index": 0}])
    assert summary["heuristics"]["ssph"]["errors"] == 1 and "Planner exceptions" in mcs.markdown(summary)


def test_wilson_interval_matches_the_closed_form():
    k, n, z = 9963, 10_000, stats.norm.ppf(0.975)
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    assert mcs.wilson(k, n) == pytest.approx((centre - half, centre + half), abs=1e-9)


def test_runtime_ratio_of_paired_samples():
    rng = np.random.default_rng(0)
    base = rng.uniform(1.0, 2.0, 500)
    ratio, lo, hi = mcs.ratio_of_means(2.0 * base, base)
    assert (ratio, lo, hi) == pytest.approx((2.0, 2.0, 2.0))
    ratio, lo, hi = mcs.ratio_of_means(base * rng.uniform(0.5, 1.5, 500), base)
    assert lo < ratio < hi and lo < 1.0 < hi


def _row(field, index, h, ok, exst, trst=3, length=1000.0, rt=1.0):
    return {
        "status": "ok" if ok else "limit",
        "field": field,
        "index": index,
        "heuristic": h,
        "success": ok,
        "exst": exst,
        "trst": trst if ok else 0,
        "length_m": length if ok else math.nan,
        "runtime_s": rt,
    }


def test_summary_counts_successes_fast_successes_and_paired_lengths():
    rows = [
        _row(0, 0, "edh", True, 10, length=1000.0, rt=2.0),
        _row(0, 0, "ssph", True, 5, length=1010.0, rt=1.0),
        _row(0, 1, "edh", True, 30, length=2000.0, rt=4.0),
        _row(0, 1, "ssph", True, 6, length=2010.0, rt=2.0),
        _row(1, 0, "edh", False, 100, rt=6.0),
        _row(1, 0, "ssph", True, 25, rt=3.0),
        _row(9, 9, "ssph", True, 1),  # no EDH row: not a paired trial, left out
    ]
    s = mcs.summarise(rows)
    assert s["trials"] == 3 and s["fields"] == 2 and s["same_search"] == 0
    edh, ssph = s["heuristics"]["edh"], s["heuristics"]["ssph"]
    assert (edh["success"], edh["fast_success"]) == (2, 1)
    assert (ssph["success"], ssph["fast_success"]) == (3, 2)
    assert edh["efficiency_ok"] == pytest.approx((3 / 10 + 3 / 30) / 2)
    assert ssph["runtime_ratio"][0] == pytest.approx(0.5)
    assert s["both"]["n"] == 2 and s["both"]["length_diff_m"] == pytest.approx(10.0)
    assert "| SSPH | 100.00" in mcs.markdown(s)
    same = [_row(0, 0, h, True, 7, length=1500.0, rt=rt) for h, rt in (("edh", 1.0), ("ssph", 2.0))]
    assert mcs.summarise(same)["same_search"] == 1


def test_a_four_trial_study_on_the_process_pool_resumes(tmp_path):
    """Two fields of two trials: one field per pool worker."""
    rows = mc.run_study(4, 2, 3, tmp_path, workers=2)
    assert len(rows) == 8 and {r["heuristic"] for r in rows} == set(mc.HEURISTICS)
    for r in rows:
        if r["success"]:
            assert r["trst"] >= 1 and r["length_m"] >= math.dist(r["start"], r["goal"]) - 1e-6
            assert r["exst"] <= mc.MAX_EXPANSIONS
    by_trial = {}
    for r in rows:  # both heuristics plan the same draw
        by_trial.setdefault((r["field"], r["index"]), set()).add((tuple(r["start"]), tuple(r["goal"]), r["course_deg"]))
    assert any(r["success"] for r in rows)
    assert len(by_trial) == 4 and all(len(v) == 1 for v in by_trial.values())
    # a stored field is not run again: mark it and read it back
    path = mc.field_path(tmp_path, 1)
    stored = json.loads(path.read_text())
    stored["rows"][0]["status"] = "from disk"
    path.write_text(json.dumps(stored))
    again = mc.run_study(4, 2, 3, tmp_path, workers=1)
    assert any(r["status"] == "from disk" for r in again)
    assert [r["success"] for r in again] == [r["success"] for r in rows]


def test_a_field_stored_under_another_study_configuration_is_run_again(tmp_path, monkeypatch):
    """Resume data may sit anywhere (here a temporary directory) and is reused only when the
    seed, the field size and the study fingerprint (configs + field spec) match."""
    ran: list[int] = []

    def fake_field(field: int, n: int, seed: int) -> list[dict]:
        ran.append(field)
        return [{"heuristic": "edh", "status": f"run {field}"}]

    monkeypatch.setattr(mc, "run_field", fake_field)
    with ThreadPoolExecutor(1) as ex:
        mc.run_study(20, 10, 3, tmp_path, ex)
        assert sorted(ran) == [0, 1]
        path = mc.field_path(tmp_path, 1)
        stored = json.loads(path.read_text())
        assert stored["study"] == mc.study_fingerprint()
        stored["study"] = "another study"
        path.write_text(json.dumps(stored))
        ran.clear()
        rows = mc.run_study(20, 10, 3, tmp_path, ex)
    assert ran == [1] and [r["status"] for r in rows] == ["run 0", "run 1"]


def test_the_trapped_trial_whose_obstacle_was_a_collection_is_planned():
    """Field 16, trial 7 (seed 1) starts trapped in a margin whose region came out as a
    GeometryCollection; it raised AttributeError in free_space before the obstacle was cut to
    its polygons."""
    cfg = mc.study_config("edh")
    tl = ObstacleTimeline(nowcast(draw_cells(mc.study_field_spec(), 16)), cfg, 2 * mc.HORIZON_S)
    trial = mc.draw_trials(tl, cfg, 16, 10, 1)[7]
    row = mc.run_trial(tl, trial, cfg)
    assert not row["status"].startswith("error") and row["success"]


def test_a_trials_searches_share_work_with_the_same_rows(field0):
    """The heuristics of a trial share the wait bound and the free spaces of the states both
    expand (search.SharedWork): the rows are those of searches alone, and each row's runtime
    counts what its search reused. Work of another configuration is refused."""
    _, tl = field0
    trial = mc.draw_trials(tl, mc.study_config("edh"), 0, 1, seed=3)[0]
    cfgs = [mc.study_config(h) for h in mc.HEURISTICS]
    shared = mc.trial_share(tl, trial, cfgs[0])
    together = [mc.run_trial(tl, trial, c, shared) for c in cfgs]
    assert shared.reused_cpu_s > 0.0
    alone = [mc.run_trial(tl, trial, c) for c in cfgs]
    times = ("runtime_s", "wall_s")
    for a, b in zip(together, alone, strict=True):
        assert {k: v for k, v in a.items() if k not in times} == pytest.approx(
            {k: v for k, v in b.items() if k not in times}, nan_ok=True, rel=0, abs=0
        )
    other = cfgs[0].with_(tas_mps=70.0)
    with pytest.raises(ValueError, match="shared work of another"):
        plan_trajectory(tl, np.array(trial.start), 0.0, 0.0, shared.goal, other, shared.w, shared=shared)
