"""Closed-loop reach-set scenarios (spec §9.3) flown by the JSBSim quadrotor on its EKF estimate;
numbers read back from the MCAP by the replay metrics."""

from pathlib import Path

import pytest

from sim.replay.report import log_metrics
from sim.replay.runlog import RunLog
from sim.runner import run_scenario
from sim.scenario import load_scenario

pytestmark = pytest.mark.closed_loop

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios" / "reachset"
MAP_MARGIN_M = 0.5  # MapConfig.safety_margin


def test_building_is_avoided_and_the_mission_completes(tmp_path):
    out = tmp_path / "building.mcap"
    scenario, text = load_scenario(SCENARIOS / "building.toml")
    run_scenario(scenario, out, scenario_text=text)
    m = log_metrics(RunLog(out))["vehicles"]["quad"]
    assert m["mission"]["complete"]
    assert 40.0 <= m["mission"]["time_s"] <= 40.0 * 1.5  # 200 m at 5 m/s, detour within +50 %
    clearance = m["clearance"]["obstacle.building"]["distance_m"]
    assert clearance > MAP_MARGIN_M
