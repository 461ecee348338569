"""MPTP in closed loop: the JSBSim HAPS, on its EKF estimate, flies MPTP plans made on storm
nowcasts and never enters a true storm cell; the same flight without MPTP does. The thesis's
scenarios (two continuous avoidances, holding, moving goal) are flown at the scale that keeps the
turn radius relative to the storms (CI) and at full size (``-m slow``, ~2 h of flight each)."""

import re

import numpy as np
import pytest

from guidance.mptp.margins import turn_cut_m
from sim.replay.report import log_metrics
from sim.scenario import ScenarioError, parse_scenario
from sim.testbeds import mptp_thesis as S
from sim.testbeds.mptp_haps import matched_scale
from sim.testbeds.mptp_haps import scenario_data as thesis_scenario_data

pytestmark = pytest.mark.closed_loop


def _fly(fly, scenario_data, planner: str, estimator: str = "ekf", duration: float | None = None):
    data = scenario_data("mptp/storm_crossing")
    data["vehicle"][0]["planner"]["type"] = planner
    data["vehicle"][0]["estimator"] = estimator
    run = fly(data, planner, duration=duration)
    return run.result, run.log


@pytest.mark.slow  # in CI: the matched-scale thesis flights below (MPTP on synthetic storm fields)
def test_mptp_avoids_the_storms_and_reaches_the_goal(fly, scenario_data):
    result, log = _fly(fly, scenario_data, "mptp")
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


def test_without_mptp_the_same_flight_enters_a_storm(fly, scenario_data):
    """The first 1000 s of the straight 50 km leg (26 km of it): the first cell, 3 km in radius
    and 22 km east drifting east at 2 m/s, lies across it."""
    # the geometry alone decides this one: perfect estimates
    result, log = _fly(fly, scenario_data, "follow_mission", "perfect", duration=1000.0)
    assert result.status == "duration_elapsed"
    assert log_metrics(log)["vehicles"]["haps"]["storms"]["time_inside_s"] > 0.0


def _gap_opens_s(scenario, margin_m: float) -> float:
    """When the plug (storm 2, drifting south) and its margin ``margin_m`` [m] leave the band of
    the walls (storm 0) and their margin: the corridor opens [s]."""
    wall, plug = np.array(scenario.weather.storm[0].points), scenario.weather.storm[2]
    return (np.max(np.array(plug.points)[:, 0]) + margin_m - (wall[:, 0].min() - margin_m)) / abs(plug.drift_north)


@pytest.mark.slow  # in CI: tests/test_mptp_scenarios.py flies the same corridor open loop, replanning
def test_an_opening_corridor_is_waited_for_in_closed_loop(fly):
    """Resolution completeness in closed loop: the gap between two storm walls is plugged by a
    cell drifting out of it; the HAPS reaches the goal through the gap after it opened (it
    would reach the walls 6 min after the start), is never inside a cell and is never told
    there is no solution."""
    run = fly("mptp/opening_corridor")
    assert run.result.status == "completed"
    scenario, log = run.scenario, run.log
    assert log_metrics(log)["vehicles"]["haps"]["storms"]["time_inside_s"] == 0.0
    assert all(m["status"] != "no_solution" for m in log.topic("/haps/plan").messages)
    wall = np.array(scenario.weather.storm[0].points)
    opens_s = _gap_opens_s(scenario, scenario.vehicle[0].planner.options.safety_single_m[0])
    truth = log.topic("/haps/truth/state")
    k = int(np.argmax(truth["pos_ned"][:, 0] >= wall[:, 0].mean()))
    assert truth["pos_ned"][k, 0] >= wall[:, 0].mean(), "never crossed the walls"
    assert abs(truth["pos_ned"][k, 1]) < np.min(np.abs(np.array(scenario.weather.storm[1].points)[:, 1]))  # the gap
    assert truth.t[k] > opens_s


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(1, 21))
def test_a_corridor_opening_after_20_min_is_held_for_and_taken(fly, scenario_data, seed):
    """scenarios/mptp/corridor_opens.toml (default search options) on seeds 1-20: the corridor
    opens at 1182 s, so no arrival is earlier than 1797 s (the file's header). The HAPS holds
    south of the walls (never without a solution), crosses through the gap after it opened, is
    never inside a true cell and arrives within 5 % of the optimum under the planner's model
    (issue 20), which is at or above the bound with the planner's extra margin (simplification
    and turn cut) on the walls and the plug, at the goal's acceptance radius. Before plan keeping
    (and the follower keeping its place on a kept plan) seed 7 had not arrived after 2400 s; with
    the search capped at 120 expansions seed 18 arrived 9.4 % late (its first complete plan came
    at 720 s, from a state that had drifted on partial plans)."""
    data = scenario_data("mptp/corridor_opens")
    data["seed"] = seed
    run = fly(data, f"corridor_opens_{seed}")
    assert run.result.status == "completed"
    scenario, log = run.scenario, run.log
    haps = log_metrics(log)["vehicles"]["haps"]
    assert haps["storms"]["time_inside_s"] == 0.0
    plans = log.topic("/haps/plan").messages
    assert all(m["status"] != "no_solution" for m in plans)
    wall = np.array(scenario.weather.storm[0].points)
    mission = scenario.vehicle[0].mission

    def earliest_arrival(margin_m: float, short_m: float) -> float:
        """The gap's opening with margins ``margin_m``, then straight on at cruise speed from the
        walls' margin to ``short_m`` before the goal [s]."""
        south = wall[:, 0].min() - margin_m
        return _gap_opens_s(scenario, margin_m) + (mission.waypoints[0].north - short_m - south) / mission.cruise_speed

    margin = scenario.vehicle[0].planner.options.safety_line_m[0]
    opens_s, earliest = _gap_opens_s(scenario, margin), earliest_arrival(margin, 0.0)
    truth = log.topic("/haps/truth/state")
    k = int(np.argmax(truth["pos_ned"][:, 0] >= wall[:, 0].mean()))
    assert truth["pos_ned"][k, 0] >= wall[:, 0].mean(), "never crossed the walls"
    assert abs(truth["pos_ned"][k, 1]) < np.min(np.abs(np.array(scenario.weather.storm[1].points)[:, 1]))
    assert truth.t[k] > opens_s
    arrived = haps["mission"]["time_s"]  # the goal reached (by the estimate, within the acceptance radius)
    assert arrived >= earliest
    cfg = scenario.vehicle[0].planner.options.config()
    assert arrived <= 1.05 * earliest_arrival(margin + cfg.simplify_tol_m + turn_cut_m(cfg), mission.acceptance_radius)


@pytest.mark.parametrize(
    "options, message",
    [
        ({"goal_track": [[0, 1, 2], [0, 3, 4]]}, "goal_track: expected rows [t, north, east]"),
        ({"goal_track": "x"}, "planner.options.goal_track: Input should be a valid tuple"),
        ({"mission_area": [[0, 0], [1, 1]]}, "mission_area: expected >= 3 vertices"),
        ({"heuristic": "astar"}, "planner.options.heuristic: Input should be 'dijkstra', 'edh' or 'ssph'"),
    ],
)
def test_bad_mptp_options_are_one_line_scenario_errors(scenario_data, options, message):
    data = scenario_data("mptp/storm_crossing")
    data["vehicle"][0]["planner"]["options"] = options
    with pytest.raises(ScenarioError, match=re.escape(message)) as err:
        parse_scenario(data, "storm_crossing")
    assert "\n" not in str(err.value)


THESIS = [S.scenario_1, S.scenario_2, S.holding_scenario, S.moving_goal_scenario]
THESIS_IDS = ["scenario1", "scenario2", "holding", "moving_goal"]


def _fly_thesis(fly, make, full_size: bool):
    sc = make()
    data = thesis_scenario_data(sc, 1.0 if full_size else matched_scale(sc))
    run = fly(data, data["name"])
    return sc, data, run.result, run.log


def _check_thesis_flight(sc, data, result, log):
    """Reached the goal (the moving one where it is at arrival), never inside a true storm cell,
    and held first in the holding scenario; all read from the log."""
    assert result.status == "completed", result.status
    haps = log_metrics(log)["vehicles"]["haps"]
    assert haps["storms"]["time_inside_s"] == 0.0
    assert haps["storms"]["min_distance_m"] > 0.0
    truth = log.topic("/haps/truth/state")
    arrival = haps["mission"]["time_s"]
    at = np.argmin(np.abs(truth.t - arrival))
    opts = data["vehicle"][0]["planner"]["options"]
    if "goal_track" in opts:
        track = np.array(opts["goal_track"])
        goal = np.array([np.interp(arrival, track[:, 0], track[:, k]) for k in (1, 2)])
    else:
        wp = data["vehicle"][0]["mission"]["waypoints"][0]
        goal = np.array([wp["north"], wp["east"]])
    miss = float(np.linalg.norm(truth["pos_ned"][at, :2] - goal))
    assert miss < 2.0 * data["vehicle"][0]["mission"]["acceptance_radius"], f"{miss:.0f} m from the goal"
    plans = log.topic("/haps/plan").messages
    assert {m["planner"] for m in plans} == {"mptp"}
    if sc.name == "holding":
        assert any(m["status"] == "degraded" for m in plans)  # it held ...
        start = np.array([data["vehicle"][0]["initial"][k] for k in ("north", "east")])
        beeline_s = np.linalg.norm(goal - start) / data["vehicle"][0]["mission"]["cruise_speed"]
        assert arrival > 2.0 * beeline_s  # ... then proceeded


# Slow: in CI the thesis scenarios fly open loop (tests/test_mptp_scenarios.py) and a hold is
# flown closed loop by tests/test_mptp_holding_speed.py.
@pytest.mark.slow
@pytest.mark.parametrize("make", THESIS, ids=THESIS_IDS)
def test_thesis_scenarios_scaled(fly, make):
    _check_thesis_flight(*_fly_thesis(fly, make, full_size=False))


@pytest.mark.slow
@pytest.mark.parametrize("make", THESIS, ids=THESIS_IDS)
def test_thesis_scenarios_full_size(fly, make):
    _check_thesis_flight(*_fly_thesis(fly, make, full_size=True))
