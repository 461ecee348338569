"""MPTP in closed loop: the JSBSim HAPS, on its EKF estimate, flies MPTP plans made on storm
nowcasts and never enters a true storm cell; the same flight without MPTP does."""

import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from sim.replay.report import log_metrics
from sim.replay.runlog import RunLog
from sim.runner import run_scenario
from sim.scenario import parse_scenario

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "mptp" / "storm_crossing.toml"
pytestmark = pytest.mark.closed_loop


def _fly(tmp_path, planner: str, estimator: str = "ekf"):
    data = tomllib.loads(SCENARIO.read_text())
    data["vehicle"][0]["planner"]["type"] = planner
    data["vehicle"][0]["estimator"] = estimator
    path = tmp_path / f"{planner}.mcap"
    result = run_scenario(parse_scenario(data, str(SCENARIO)), path, scenario_text=tomli_w.dumps(data))
    return result, RunLog(path)


def test_mptp_avoids_the_storms_and_reaches_the_goal(tmp_path):
    result, log = _fly(tmp_path, "mptp")
    assert result.status == "completed"
    haps = log_metrics(log)["vehicles"]["haps"]
    assert haps["storms"]["time_inside_s"] == 0.0
    assert haps["storms"]["min_distance_m"] > 1000.0  # outside the cells, with margin to spare
    plans = log.topic("/haps/plan")
    assert {m["planner"] for m in plans.messages} == {"mptp"}
    # the flight detours: more than the 50 km straight line
    pos = log.topic("/haps/truth/state")["pos_ned"]
    flown = float(np.sum(np.linalg.norm(np.diff(pos[:, :2], axis=0), axis=1)))
    assert flown > 50_500.0
    assert log.has("/haps/plan/map") and log.has("/world/weather/storms")


def test_without_mptp_the_same_flight_enters_a_storm(tmp_path):
    result, log = _fly(tmp_path, "follow_mission", "perfect")  # the geometry alone decides this one
    assert result.status == "completed"
    assert log_metrics(log)["vehicles"]["haps"]["storms"]["time_inside_s"] > 0.0
