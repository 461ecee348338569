"""MPTP in wind: the air-mass frame (wind.py), the timeline drifting with it, the forecast wired
from the scenario, and arrival predictions that hold in a true wind where wind-blind ones do not.

The world of the flight tests is scenarios/mptp/wind_crossing.toml: two scripted cells (exact
nowcasts), a 50 km leg east, a steady 15 m/s wind towards 053 deg."""

import dataclasses
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
import shapely
import tomli_w
from shapely.geometry import box

from aircraft.registry import get_airframe
from guidance.mptp.config import MptpConfig
from guidance.mptp.goal import GoalTrack
from guidance.mptp.timeline import ObstacleTimeline
from guidance.mptp.wind import WindForecast, air_goal, to_air, to_ground
from sim.core.mission import Mission
from sim.core.plan import Threats
from sim.core.threats import StormSnapshot
from sim.planner_registry import make_planner
from sim.scenario import load_scenario, parse_scenario
from sim.testbeds.mptp_openloop import flown_times, ground_speed, run_open_loop, vehicle_state
from sim.testbeds.mptp_thesis import Scenario
from sim.vehicle_setup import scenario_planner
from sim.weather import WeatherService
from sim.wind_field import WindField

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "mptp" / "wind_crossing.toml"


def test_wind_forecast_interpolates_by_height_and_holds_beyond():
    wf = WindForecast(np.array([0.0, 10_000.0]), np.array([[0.0, 0.0], [10.0, -20.0]]))
    assert np.allclose(wf.at(5_000.0), [5.0, -10.0])
    assert np.allclose(wf.at(30_000.0), [10.0, -20.0]) and np.allclose(wf.at(-5.0), [0.0, 0.0])
    assert np.allclose(WindForecast.steady(3.0, 4.0).at(18_000.0), [3.0, 4.0])
    with pytest.raises(ValueError, match="increasing heights"):
        WindForecast(np.array([1.0, 0.0]), np.zeros((2, 2)))


def test_air_frame_maps_a_ground_goal_to_one_drifting_at_minus_the_wind():
    w = np.array([9.0, 12.0])
    p = np.array([[100.0, 200.0], [0.0, 0.0]])
    t = np.array([50.0, 400.0])
    assert np.allclose(to_ground(to_air(p, t, w, 20.0), t, w, 20.0), p)
    g = air_goal(GoalTrack.fixed([0.0, 50_000.0]), w, 0.0, 100.0, 4000.0)
    assert np.allclose(g.at(1000.0), [0.0, 50_000.0] - 1000.0 * w)
    # a goal that moves on the ground keeps its knots
    track = GoalTrack(np.array([0.0, 1000.0]), np.array([[0.0, 0.0], [1000.0, 0.0]]))
    assert np.allclose(air_goal(track, w, 0.0, 0.0, 2000.0).at(500.0), [500.0, 0.0] - 500.0 * w)


def test_timeline_in_the_air_frame_moves_a_static_cell_at_minus_the_wind():
    cfg = MptpConfig(safety_single_m=(1000.0,) * 3, sigma_front_mps=0.0, sigma_back_mps=0.0)
    cell = StormSnapshot(0.0, (box(0, 0, 4000, 4000),), None)
    w = np.array([9.0, 12.0])
    ground = ObstacleTimeline([cell], cfg, 3600.0)
    air = ObstacleTimeline([cell], cfg, 3600.0, w)
    for t in (0.0, 700.0, 5000.0):  # inside the horizon and beyond its end
        moved = shapely.affinity.translate(ground.shape_at(t), *(-w * t))
        assert air.shape_at(t).symmetric_difference(moved).area < 1e-3 * moved.area
    j = 5  # an envelope holds the shapes over its interval (up to the smoothing tolerance)
    for t in np.linspace(air.level_time(j), air.level_time(j + 1), 7):
        assert air.envelope(j).buffer(cfg.simplify_tol_m).contains(air.shape_at(float(t)))
    assert not ground.envelope(j).buffer(cfg.simplify_tol_m).contains(air.shape_at(air.level_time(j)))


def test_ground_speed_of_a_crabbed_leg():
    w = np.array([0.0, 10.0])
    assert float(ground_speed(0.0, 26.0, w)) == pytest.approx(24.0)  # 10 m/s cross wind
    assert float(ground_speed(math.pi / 2, 26.0, w)) == pytest.approx(36.0)  # tail wind
    times = flown_times(np.array([[0.0, 0.0], [0.0, 3600.0], [0.0, 0.0]]), 10.0, 26.0, w)
    assert np.allclose(times, [10.0, 110.0, 335.0])


def test_the_forecast_comes_from_the_scenario_wind_and_its_options_act():
    scenario, _ = load_scenario(SCENARIO)
    v = scenario.vehicle[0]
    mission = np.array([[0.0, 50_000.0, -18_000.0]])
    m = Mission(mission, 26.0, 500.0)
    wind = (scenario.wind.north, scenario.wind.east)
    p = make_planner("mptp", m, "fixed_wing", v.planner.options, wind_ne_mps=wind)
    assert np.allclose(p.wind.at(18_000.0), [9.0, 12.0])
    p = make_planner("mptp", m, "fixed_wing", {"wind_error_ne_mps": [2.0, -3.0]}, wind_ne_mps=wind)
    assert np.allclose(p.wind.at(18_000.0), [11.0, 9.0])
    assert make_planner("mptp", m, "fixed_wing", {"wind_forecast": "none"}, wind_ne_mps=wind).wind is None
    with pytest.raises(ValueError, match="wind_error_ne_mps"):
        make_planner("mptp", m, "fixed_wing", {"wind_error_ne_mps": [1.0]})


def test_the_standard_profile_is_the_forecast_at_the_planned_altitude():
    """[wind] standard = "midlatitude_jet" reaches the MPTP as a height profile above the origin
    (with the error option added at every height, a copy, not the truth's WindField), and a
    replan takes the wind at the plan's flight level (mean of the start's and goal's heights)."""
    data = tomllib.loads(SCENARIO.read_text())
    data["wind"] = {"standard": "midlatitude_jet"}
    data["origin"]["altitude"] = 500.0
    data["vehicle"][0]["planner"]["options"]["wind_error_ne_mps"] = [1.0, -2.0]
    scenario = parse_scenario(data)
    v = scenario.vehicle[0]
    af = get_airframe(v.aircraft)
    m = Mission(np.array([[0.0, 50_000.0, -17_500.0]]), 26.0, 500.0)
    p = scenario_planner(v, m, af, af.make_controller(v.gains).gains, scenario.wind, 500.0)
    truth = WindField(scenario.wind)
    for up in (1_500.0, 11_000.0, 17_500.0, 19_500.0):
        assert np.allclose(p.wind.at(up), truth.at(up + 500.0, 0.0)[:2] + [1.0, -2.0])
    assert not isinstance(p.wind, WindField)
    est = dataclasses.replace(
        vehicle_state(0.0, np.zeros(2), math.pi / 2, 26.0), pos_ned=np.array([0.0, 0.0, -15_500.0])
    )
    p.plan(est, Threats(storms=[]), 0.0)
    level = 0.5 * (-float(est.pos_ned[2]) + 17_500.0)
    assert np.allclose(p.wind_ne, truth.at(level + 500.0, 0.0)[:2] + [1.0, -2.0])


HOURS = [  # two hourly tables on different altitude rows: calm-ish at t = 0, a jet an hour later
    {"time": 0.0, "levels": [{"altitude": 0.0, "east": 2.0}, {"altitude": 20_000.0, "east": 4.0}]},
    {
        "time": 3600.0,
        "levels": [
            {"altitude": 5_000.0, "north": -3.0, "east": 10.0},
            {"altitude": 12_000.0, "north": 1.0, "east": 30.0},
            {"altitude": 18_000.0, "north": 2.0, "east": 15.0},
        ],
    },
]


def _hourly_planner(origin_alt: float = 500.0):
    data = tomllib.loads(SCENARIO.read_text())
    data["wind"] = {"north": 1.0, "hours": HOURS}
    data["origin"]["altitude"] = origin_alt
    scenario = parse_scenario(data)
    v = scenario.vehicle[0]
    af = get_airframe(v.aircraft)
    m = Mission(np.array([[0.0, 50_000.0, -17_500.0]]), 26.0, 500.0)
    return scenario_planner(v, m, af, af.make_controller(v.gains).gains, scenario.wind, origin_alt), scenario


def test_hourly_wind_tables_are_the_forecast_in_height_and_time():
    """[[wind.hours]] reach the MPTP as a forecast that equals the scenario's wind at every
    height and time (tables on different altitude rows, interpolated in time, held beyond the
    first and last hour; the steady part included), not the first hour's table alone."""
    p, scenario = _hourly_planner()
    truth = WindField(scenario.wind)
    for t in (0.0, 900.0, 1800.0, 3600.0, 7200.0):
        for up in (-1_000.0, 2_000.0, 8_000.0, 11_500.0, 15_000.0, 17_500.0, 25_000.0):
            assert np.allclose(p.wind.at(up, t), truth.at(up + 500.0, t)[:2], atol=1e-12), (t, up)
    assert not np.allclose(p.wind.at(11_500.0, 3600.0), p.wind.at(11_500.0, 0.0))


def test_a_replan_takes_the_forecast_at_its_own_time():
    """Each replan takes the wind steady over its plan from the forecast at the replan's time:
    an hour in, the jet of the second table, not the wind of the start."""
    p, scenario = _hourly_planner()
    truth = WindField(scenario.wind)
    est = dataclasses.replace(
        vehicle_state(0.0, np.zeros(2), math.pi / 2, 26.0), pos_ned=np.array([0.0, 0.0, -15_500.0])
    )
    level = 0.5 * (-float(est.pos_ned[2]) + 17_500.0) + 500.0  # MSL
    for t in (0.0, 1800.0, 3600.0):
        p.plan_ = None
        p.plan(dataclasses.replace(est, t=t), Threats(storms=[]), t)
        assert np.allclose(p.wind_ne, truth.at(level, t)[:2]), t
    assert p.wind_ne[1] > 15.0  # the jet, an hour in (2.0-4.0 m/s east at the start)


def test_the_estimated_wind_is_the_ground_minus_the_air_velocity_over_a_period():
    """``wind_forecast = "estimate"``: no forecast is built; each replan takes the mean, over the
    last replan period, of what the estimate implies (ground velocity minus the TAS along the
    heading, the climb taken out), so a wind that changes is followed within a period; the
    forecast's error option does not touch it."""
    m = Mission(np.array([[0.0, 50_000.0, -18_000.0]]), 26.0, 500.0)
    options = {"wind_forecast": "estimate", "wind_error_ne_mps": [5.0, 5.0], "nav_std_max_m": math.inf}
    p = make_planner("mptp", m, "fixed_wing", options, wind_ne_mps=(-7.0, 3.0))
    assert p.wind is None
    period = p.cfg.replan_period_s

    def fly(t: float, wind: np.ndarray, heading: float) -> None:
        air = 26.0 * np.array([math.cos(heading), math.sin(heading)])
        est = dataclasses.replace(
            vehicle_state(t, np.zeros(2), heading, 26.0),
            pos_ned=np.array([0.0, 0.0, -18_000.0]),
            vel_ned=np.array([*(air * math.sqrt(1 - 0.5**2 / 26.0**2) + wind), -0.5]),  # climbing 0.5 m/s
            euler=np.array([0.0, 0.0, heading]),
        )
        p.plan(est, Threats(storms=[]), t)

    for k, t in enumerate(np.arange(0.0, period, 10.0)):
        fly(float(t), np.array([9.0, 12.0]), 0.3 * k)  # headings spread over the circle
    assert np.allclose(p.wind_ne, [9.0, 12.0], atol=1e-9)
    for k, t in enumerate(np.arange(period, 2 * period + 1.0, 10.0)):
        fly(float(t), np.array([-4.0, 2.0]), 0.3 * k)
    assert np.allclose(p.wind_ne, [-4.0, 2.0], atol=1e-9)  # a period later, only the new wind


def _open_loop_world() -> tuple[Scenario, np.ndarray]:
    scenario, _ = load_scenario(SCENARIO)
    field = WeatherService(scenario.weather, scenario.seed).field
    cfg = scenario.vehicle[0].planner.options.config()
    sc = Scenario("wind crossing", np.zeros(2), math.pi / 2, GoalTrack.fixed([0.0, 50_000.0]), cfg, field, 20)
    return sc, np.array([scenario.wind.north, scenario.wind.east])


def _predicted_arrivals(run) -> np.ndarray:
    """Arrival time [s] predicted by every complete plan (one reaching the goal)."""
    return np.array([p.t + p.diagnostics["eta_s"] for p in run.plans if p.status.value == "ok"])


def test_in_a_true_wind_the_air_frame_plans_predict_the_flown_arrival():
    """Kinematic aircraft (plan legs flown on the ground at the planning TAS, crabbed) in the
    scenario's true 15 m/s wind, replanning every 5 min on exact nowcasts: every complete plan
    made with the forecast predicts the arrival within 3 % (it is exact: straight air-frame
    legs are straight ground legs); the wind-blind plans miss it by more; neither enters a cell."""
    sc, wind = _open_loop_world()
    aware = run_open_loop(sc, wind_true=wind, wind_forecast=WindForecast.steady(*wind))
    blind = run_open_loop(sc, wind_true=wind)
    for run in (aware, blind):
        assert math.isfinite(run.arrived_s)
        for ne, t in zip(run.flown_ne, run.flown_t, strict=True):
            cells = shapely.union_all(list(sc.storms.truth(float(t)).cells))
            assert not shapely.contains_xy(cells, ne[0], ne[1]), f"inside a storm at t={t}"
    err_aware = np.abs(_predicted_arrivals(aware) - aware.arrived_s) / aware.arrived_s
    err_blind = np.abs(_predicted_arrivals(blind) - blind.arrived_s) / blind.arrived_s
    assert len(err_aware) and err_aware.max() < 0.03
    assert err_blind[0] > 0.03 and err_blind[0] > 10 * err_aware[0]


# the scenario's steady 15 m/s wind, and the standard profile alone (8 m/s towards east at the
# 18 km flight level: a tailwind on the eastbound leg)
CLOSED_LOOP_WINDS = {"steady_15": None, "standard_profile": {"standard": "midlatitude_jet"}}


def _closed_loop_arrival_errors(
    tmp_path, forecast: str, wind: dict | None, seed: int | None = None
) -> tuple[float, float]:
    """The scenario flown by the JSBSim HAPS on its EKF with ``wind_forecast = forecast`` (and
    ``wind`` as its ``[wind]`` table, None: the file's; ``seed``, None: the file's): it arrives,
    never inside a true cell. Returns the relative errors of two complete plans' predicted
    arrivals against the flown one, each over the time from the plan to the flown arrival (from
    the MCAP): the first complete plan's (made 10 s after the start, after the navigation wait)
    and that of the plan flown to the goal (the last new one; later replans kept it). The
    flight arrives when the follower takes the goal as reached, within the acceptance radius of
    it on the last leg, so a plan's predicted arrival is its time at that distance from the goal
    (the plan's goal time is ~15 s later at the file's 500 m)."""
    from sim.replay.report import log_metrics
    from sim.replay.runlog import RunLog
    from sim.runner import run_scenario

    data = tomllib.loads(SCENARIO.read_text())
    data["vehicle"][0]["planner"]["options"]["wind_forecast"] = forecast
    if wind is not None:
        data["wind"] = wind
    if seed is not None:
        data["seed"] = seed
    path = tmp_path / f"{forecast}.mcap"
    scenario = parse_scenario(data, str(SCENARIO))
    run_scenario(scenario, path, scenario_text=tomli_w.dumps(data))
    log = RunLog(path)
    haps = log_metrics(log)["vehicles"]["haps"]
    arrived = haps["mission"]["time_s"]
    assert arrived is not None and haps["storms"]["time_inside_s"] == 0.0
    plans = [m for m in log.topic("/haps/plan").messages if m["status"] == "ok" and "eta_s" in m["diagnostics"]]
    assert plans[-1]["t"] < arrived
    radius = scenario.vehicle[0].mission.acceptance_radius  # [m]

    def error(m: dict) -> float:
        a, b = np.asarray(m["positions"], float)[-2:, :2]
        ta, tb = m["times"][-2:]
        assert tb == pytest.approx(m["t"] + m["diagnostics"]["eta_s"])
        predicted = tb - min(radius / float(np.linalg.norm(b - a)), 1.0) * (tb - ta)
        return abs(predicted - arrived) / (arrived - m["t"])

    return error(plans[0]), error(plans[-1])


@pytest.mark.slow  # in CI: the open-loop air-frame test above; tests/test_wind.py flies JSBSim in wind
@pytest.mark.closed_loop
@pytest.mark.parametrize("wind", CLOSED_LOOP_WINDS.values(), ids=CLOSED_LOOP_WINDS.keys())
def test_closed_loop_in_wind_predicted_arrival_matches_the_flight(tmp_path, wind):
    """JSBSim HAPS on its EKF in the scenario's steady 15 m/s wind, and in the standard profile:
    with the forecast the first complete plan's predicted arrival, and the flown plan's, are
    within 3 % of the flown one."""
    assert max(_closed_loop_arrival_errors(tmp_path, "scenario", wind)) < 0.03


@pytest.mark.slow
@pytest.mark.closed_loop
@pytest.mark.parametrize("wind", CLOSED_LOOP_WINDS.values(), ids=CLOSED_LOOP_WINDS.keys())
def test_closed_loop_with_the_estimated_wind_predicts_the_arrival(tmp_path, wind):
    """The same flights with no forecast, the planner measuring the wind from its EKF estimate:
    the first complete plan's predicted arrival, and the flown plan's, within 3 % of the flown one."""
    assert max(_closed_loop_arrival_errors(tmp_path, "estimate", wind)) < 0.03


@pytest.mark.slow
@pytest.mark.closed_loop
@pytest.mark.parametrize("wind", CLOSED_LOOP_WINDS.values(), ids=CLOSED_LOOP_WINDS.keys())
def test_closed_loop_without_the_forecast_misses_the_arrival(tmp_path, wind):
    """The same flights wind-blind: both predictions are off by more than 3 % (in CI the open-loop
    test above checks the wind-blind miss)."""
    assert min(_closed_loop_arrival_errors(tmp_path, "none", wind)) > 0.03


@pytest.mark.slow
@pytest.mark.closed_loop
@pytest.mark.parametrize("seed", range(1, 21))
@pytest.mark.parametrize("forecast", ["scenario", "estimate", "none"])
@pytest.mark.parametrize("wind", CLOSED_LOOP_WINDS.values(), ids=CLOSED_LOOP_WINDS.keys())
def test_the_flown_plans_arrival_holds_across_seeds_and_only_with_the_wind(tmp_path, wind, forecast, seed):
    """The steady 15 m/s flight and the standard profile's on 20 seeds (sensor noise, so the
    estimates and the closed loop's start differ): with the forecast and with the estimated wind
    the plan flown to the goal predicts the arrival within 3 %; wind-blind both plans miss by
    more. (The first plan, made 10 s after the in-flight start, during the controller's start
    transient, is within 3 % on 19 of 20 steady-wind seeds with the forecast: docs/mptp.md,
    scripts/mptp_wind_seeds.py.)"""
    first, flown = _closed_loop_arrival_errors(tmp_path, forecast, wind, seed)
    if forecast == "none":
        assert min(first, flown) > 0.03
    else:
        assert flown < 0.03
