"""Scenarios flown from nowcast GeoJSON files (``[weather] nowcast_files``): validation, the
weather service issuing each file at its first step's time, and the shipped closed-loop case
(scenarios/mptp/nowcast_crossing.toml) read back from its MCAP."""

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest
import shapely
from shapely.geometry import box

from sim.core.threats import StormSnapshot
from sim.nowcast_files import load_nowcast, save_nowcast
from sim.scenario import ScenarioError, load_scenario, parse_scenario
from sim.weather import WeatherService

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "mptp" / "nowcast_crossing.toml"


def _series(folder: Path, issues=(0.0, 300.0)) -> list[str]:
    names = []
    for k, t in enumerate(issues):
        cell = box(1000.0 * k, 0.0, 1000.0 * k + 2000.0, 2000.0)
        snaps = [
            StormSnapshot(t + d, (shapely.affinity.translate(cell, 0.0, 10.0 * d),), np.array([[0.0, 10.0]]))
            for d in (0.0, 600.0)
        ]
        name = f"nc{k}.geojson"
        save_nowcast(folder / name, snaps)
        names.append(name)
    return names


def _scenario(folder: Path, weather: dict) -> dict:
    data = tomllib.loads(SCENARIO.read_text())
    data["weather"] = weather
    path = folder / "s.toml"
    path.write_text("")  # parse_scenario resolves files against the folder of an existing source
    return data


def test_nowcast_files_are_relative_to_the_scenario_and_validated(tmp_path):
    names = _series(tmp_path)
    data = _scenario(tmp_path, {"nowcast_files": names})
    s = parse_scenario(data, str(tmp_path / "s.toml"))
    assert s.weather.nowcast_files == [str((tmp_path / n).resolve()) for n in names]
    with pytest.raises(ScenarioError, match=r"weather.nowcast_files: .*no such file: .*missing.geojson"):
        parse_scenario(_scenario(tmp_path, {"nowcast_files": ["missing.geojson"]}), str(tmp_path / "s.toml"))
    with pytest.raises(ScenarioError, match="nowcast_files replace the synthetic and scripted cells: remove cells"):
        parse_scenario(_scenario(tmp_path, {"nowcast_files": names, "cells": 3}), str(tmp_path / "s.toml"))
    with pytest.raises(ScenarioError, match=r"issued at t=0\.0 s, not after the previous file"):
        parse_scenario(_scenario(tmp_path, {"nowcast_files": names[::-1]}), str(tmp_path / "s.toml"))
    (tmp_path / "bad.geojson").write_text(json.dumps({"type": "FeatureCollection", "features": [{"properties": {}}]}))
    with pytest.raises(ScenarioError, match=r"bad.geojson: features\[0\].properties.t"):
        parse_scenario(_scenario(tmp_path, {"nowcast_files": ["bad.geojson"]}), str(tmp_path / "s.toml"))


def test_each_file_is_issued_at_its_first_step_and_the_truth_is_its_analysis(tmp_path):
    names = _series(tmp_path)
    s = parse_scenario(_scenario(tmp_path, {"nowcast_files": names}), str(tmp_path / "s.toml"))
    w = WeatherService(s.weather, 0, s.origin_point)
    assert w.update(0.0) and w.nowcast[0].t == 0.0
    assert not w.update(290.0)
    assert w.update(300.0) and w.nowcast[0].t == 300.0 and not w.update(310.0)
    # truth: the analysis of the nowcast in force, moved by its velocities (10 m/s east)
    assert w.truth(100.0).cells[0].equals_exact(box(0.0, 1000.0, 2000.0, 3000.0), 1e-6)
    assert w.truth(400.0).cells[0].equals_exact(box(1000.0, 1000.0, 3000.0, 3000.0), 1e-6)


def _fly_and_check_the_maps(tmp_path: Path, duration_s: float | None = None) -> tuple[str, dict, int]:
    """Fly the shipped scenario (to ``duration_s`` [s] of sim time when given): it never enters
    a (file-defined) true cell, and every nowcast issued before its end is on /haps/plan/map at
    its issue time with its cells exactly as in the file (the planner's view) and the margin
    region around them. Returns the run's status, the HAPS metrics and the number of nowcasts
    checked."""
    from sim.replay.report import log_metrics
    from sim.replay.runlog import RunLog
    from sim.runner import run_scenario

    scenario, text = load_scenario(SCENARIO)
    if duration_s is not None:
        scenario = scenario.model_copy(update={"duration": duration_s})
    path = tmp_path / "run.mcap"
    result = run_scenario(scenario, path, scenario_text=text)
    log = RunLog(path)
    haps = log_metrics(log)["vehicles"]["haps"]  # the replay finds the files through the log
    assert haps["storms"]["time_inside_s"] == 0.0
    maps = log.topic("/haps/plan/map")
    by_t = {float(t): json.loads(m.geojson) for t, m in zip(maps.t, maps.messages, strict=True)}
    end_s = haps["mission"]["time_s"] if result.status == "completed" else result.sim_time_s
    issues = [p for p in scenario.weather.nowcast_files if load_nowcast(p, scenario.origin_point)[0].t < end_s]
    for p in issues:
        file_doc = json.loads(Path(p).read_text())
        t = file_doc["features"][0]["properties"]["t"]
        first = [f["geometry"]["coordinates"][0] for f in file_doc["features"] if f["properties"]["t"] == t]
        doc = by_t[t]
        storms = [f for f in doc["features"] if f["properties"]["kind"] == "storm"]
        assert [f["properties"]["t"] for f in storms] == [t] * len(first)
        for f, ring in zip(storms, first, strict=True):
            assert np.allclose(f["geometry"]["coordinates"][0], ring, atol=1e-6)
        margins = shapely.union_all(
            [shapely.geometry.shape(f["geometry"]) for f in doc["features"] if f["properties"]["kind"] == "margin"]
        )
        assert margins.contains(shapely.union_all([shapely.geometry.shape(f["geometry"]) for f in storms]))
    return result.status, haps, len(issues)


@pytest.mark.closed_loop
def test_the_first_nowcast_files_reach_the_planner_in_flight(tmp_path):
    """The shipped scenario's first 11 min (nowcasts issued at 0, 5 and 10 min)."""
    status, _, checked = _fly_and_check_the_maps(tmp_path, 660.0)
    assert status == "duration_elapsed" and checked == 3


@pytest.mark.slow
@pytest.mark.closed_loop
def test_a_scenario_flown_from_nowcast_files(tmp_path):
    """The shipped scenario whole: the mission completes, after at least 8 nowcasts."""
    status, haps, checked = _fly_and_check_the_maps(tmp_path)
    assert status == "completed" and haps["mission"]["time_s"] is not None and checked >= 8
