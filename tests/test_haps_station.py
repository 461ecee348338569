"""HAPS station keeping (mission.repeat) and the climb from launch to 18 km (slow)."""

import numpy as np
import pytest

from sim.mcap_read import read_topic
from sim.runner import run_scenario
from sim.scenario import ScenarioError, load_scenario, parse_scenario

SQUARE = [
    {"north": 1500.0, "east": 0.0, "altitude": 18_000.0},
    {"north": 1500.0, "east": 1500.0, "altitude": 18_000.0},
    {"north": 0.0, "east": 1500.0, "altitude": 18_000.0},
    {"north": 0.0, "east": 0.0, "altitude": 18_000.0},
]


def _square(repeat: bool, planner: str = "follow_mission") -> dict:
    return {
        "name": "square",
        "seed": 3,
        "duration": 700.0,
        "origin": {"lat": 47.0, "lon": 8.0},
        "vehicle": [
            {
                "name": "haps",
                "aircraft": "haps",
                "initial": {"altitude": 18_000.0, "airspeed": 26.0},
                "mission": {"cruise_speed": 26.0, "acceptance_radius": 250.0, "repeat": repeat, "waypoints": SQUARE},
                "planner": {"type": planner},
            }
        ],
    }


def test_repeat_needs_a_planner_that_plans_leg_by_leg():
    with pytest.raises(ScenarioError, match=r"mission\.repeat: only with the follow_mission or mptp planner"):
        parse_scenario(_square(True, planner="reachset"))
    assert parse_scenario(_square(True, planner="mptp")).vehicle[0].mission.repeat


@pytest.mark.closed_loop
def test_repeated_mission_keeps_station(tmp_path):
    """Without repeat the mission completes and the run stops; with it the square is flown
    again and the aircraft stays near it for the whole run."""
    once = run_scenario(parse_scenario(_square(False)), tmp_path / "once.mcap")
    assert once.status == "completed" and once.sim_time_s < 700.0
    path = tmp_path / "repeat.mcap"
    again = run_scenario(parse_scenario(_square(True)), path)
    assert again.status == "duration_elapsed"
    events = [m.message for _, m in read_topic(path, "/log")]
    assert sum("mission repeated" in e for e in events) >= 2
    pos = np.array([m["pos_ned"] for _, m in read_topic(path, "/haps/truth/state")])
    assert np.abs(pos[:, :2] - 750.0).max() < 1500.0  # within ~750 m of the square's sides


@pytest.mark.slow
@pytest.mark.closed_loop
def test_climb_from_launch_to_18_km(tmp_path):
    """The shipped launch scenario: from 100 m at 20 kt to 18 km under TECS at the EAS schedule
    and the 1 m/s climb limit, on the energy model. Zephyr S climbs in ~10 h (aircraft/haps/
    README.md, "Launch and climb"); this model is limited by TECS's 1 m/s to ~5 h."""
    scenario, text = load_scenario("scenarios/haps_climb_to_station.toml")
    path = tmp_path / "climb.mcap"
    result = run_scenario(scenario, path, scenario_text=text)
    assert result.status == "duration_elapsed"
    st = [m for _, m in read_topic(path, "/haps/truth/state")]
    t = np.array([m["t"] for m in st])
    alt = np.array([m["alt_msl_m"] for m in st])
    reached = t[alt >= 17_950.0]
    assert reached.size and 4.5 * 3600 < reached[0] < 5.5 * 3600
    climbing = alt < 17_500.0
    eas = np.array([m["eas_mps"] for m in st])[climbing]
    assert np.abs(eas[t[climbing] > 120.0] - 10.0).max() < 1.0  # the schedule's EAS
    beta = np.degrees([abs(m["beta_rad"]) for m in st])
    assert beta.max() < 15.0 and (beta > 3.0).mean() < 0.05  # ~10 deg peaks in the box's corners
    energy = [m for _, m in read_topic(path, "/haps/energy")]
    assert not energy[-1]["depleted"] and min(e["state_of_charge"] for e in energy) > 0.2
