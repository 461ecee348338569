"""Planner re-run on a log: every planner type, flown on a shipped scenario, re-run on its log
makes the same plans at the same calls (its complete inputs are logged); each plan is logged
once, at its creation."""

from pathlib import Path

import numpy as np
import pytest
from shapely.geometry import Polygon

from sim.core.plan import Plan, Threats
from sim.core.threats import IntruderTrack, LidarScan, SphereThreat, StormSnapshot
from sim.replay import rerun
from sim.replay.report import log_metrics
from sim.replay.rerun import rerun_planner
from sim.replay.runlog import RunLog
from sim.runner import run_scenario
from sim.scenario import load_scenario
from sim.vehicle_log import threats_dict, threats_from_dict

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"


def _fly(tmp_path_factory, scenario: str, duration: float) -> Path:
    sc, text = load_scenario(SCENARIOS / scenario)
    path = tmp_path_factory.mktemp("rerun") / "run.mcap"
    run_scenario(sc, path, scenario_text=text, duration=duration)
    return path


@pytest.fixture(scope="module")
def mptp_log(tmp_path_factory) -> Path:
    """The storm crossing's first 5 min: plans at 0 s (waiting for the EKF's first GNSS fix,
    nav_std_max_m), 10 and 300 s; the other 28 calls keep the plan."""
    return _fly(tmp_path_factory, "mptp/storm_crossing.toml", 300.0)


def _assert_reproduced(path: Path, vehicle: str) -> RunLog:
    log = RunLog(path)
    inputs = log.topic(f"/{vehicle}/plan/input").messages
    plans = log.topic(f"/{vehicle}/plan")
    made = [m["t"] for m in inputs if m["new_plan"]]
    assert plans.t.tolist() == made  # each plan once, at the call that made it
    assert [m["t"] for m in plans.messages] == made
    rep = rerun_planner(path, vehicle)
    assert rep.differences == []
    assert rep.plans == rep.same == len(made) > 0
    assert rep.max_position_diff_m == 0.0 and rep.max_time_diff_s == 0.0
    return log


@pytest.mark.parametrize(
    ("scenario", "vehicle", "duration", "records", "sensed"),
    [
        ("geometric/s3b_moving_main.toml", "quad", 25.0, "candidates", "intruders"),
        ("reachset/s6_converging.toml", "uas1", 20.0, "decision", "intruders"),
        ("reachset/building_lidar.toml", "quad", 20.0, "decision", "lidar_hits"),
        ("rules/s9_converging.toml", "uas1", 30.0, "rules", "intruders"),
        ("rules/s9_converging_utm.toml", "uas1", 30.0, "rules", "intruders"),  # and the UTM's directives
    ],
)
def test_avoidance_planner_rerun_reproduces_every_plan(tmp_path_factory, scenario, vehicle, duration, records, sensed):
    log = _assert_reproduced(_fly(tmp_path_factory, scenario, duration), vehicle)
    threats = log.topic(f"/{vehicle}/threats").messages
    assert any(m[sensed] for m in threats)  # it planned on sensed traffic or LiDAR returns
    assert log.has(f"/{vehicle}/plan/{records}")  # the planner's own logic ran (rules: rule decisions)


def test_mptp_rerun_reproduces_every_plan_and_needs_the_storm_velocities_and_observations(mptp_log, monkeypatch):
    log = _assert_reproduced(mptp_log, "haps")
    assert len(log.topic("/haps/plan")) == 3  # the navigation wait at 0 s, then 10 and 300 s
    inputs = log.topic("/haps/plan/input").messages
    assert sum(not m["new_plan"] for m in inputs) == len(inputs) - 3
    m = RunLog(mptp_log)
    assert m.topic("/haps/plan/latency").t.tolist() == [0.0, 10.0, 300.0]  # latency of real replans only
    latency = log_metrics(m)["vehicles"]["haps"]["planner_latency"]
    assert latency["count"] == 3 and latency["cache_hits"] == len(inputs) - 3
    # the cell velocities act: without them the nowcast's storms do not move and the plans differ
    still = rerun.storms_from_dicts
    monkeypatch.setattr(rerun, "storms_from_dicts", lambda d: still([{**s, "velocities_ne": None} for s in d]))
    blind = rerun_planner(mptp_log, "haps")
    assert blind.same < blind.plans == 3

    # the estimates the MPTP observed between its calls (1 Hz, from its first call on) act too:
    # without them the 10 s plan flies the mean airspeed of two calls, not of 11 samples
    assert m.topic("/haps/plan/observation").t.tolist() == [float(t) for t in range(1, 301)]
    monkeypatch.undo()
    monkeypatch.setattr(rerun._Observations, "deliver", lambda self, planner, t: None)
    unobserved = rerun_planner(mptp_log, "haps")
    assert unobserved.same < unobserved.plans == 3


def test_follow_mission_counts_every_call_as_a_new_plan_and_no_cache_hit(tmp_path_factory):
    path = _fly(tmp_path_factory, "quad_square_mission.toml", 5.0)
    log = _assert_reproduced(path, "quad")
    assert len(log.topic("/quad/plan")) == len(log.topic("/quad/plan/input")) == len(log.topic("/quad/plan/latency"))


def test_threats_round_trip_through_the_log_record_field_by_field():
    a = np.arange
    square = Polygon([(0, 0), (10, 0), (10, 10), (0, 10)])
    th = Threats(
        intruders=[IntruderTrack("i", 1.5, a(3.0), a(3.0) + 1, 2.0, np.eye(3), 2 * np.eye(3), True)],
        spheres=[SphereThreat("s", 1.0, a(3.0) + 5, 3.0, a(3.0) - 1, 4 * np.eye(3))],
        storms=[StormSnapshot(60.0, (square,), np.array([[1.0, -2.0]]))],
        lidar=LidarScan(2.0, a(3.0), np.eye(3), np.array([5.0, 7.0, 9.0]), np.array([True, False, True]), 50.0),
    )
    back = threats_from_dict(threats_dict(2.0, th), ["o"], ["g"])  # type: ignore[list-item]
    assert back.obstacles == ["o"] and back.geofences == ["g"]
    for old, new in [(th.intruders[0], back.intruders[0]), (th.spheres[0], back.spheres[0]), (th.lidar, back.lidar)]:
        for name in old.__slots__:
            assert np.array_equal(getattr(old, name), getattr(new, name)), name
    s0, s1 = th.storms[0], back.storms[0]
    assert s1.t == s0.t and s1.cells[0].equals_exact(s0.cells[0], 0.0)
    assert np.array_equal(s1.velocities_ne, s0.velocities_ne)


def _fly_commanded(tmp_path: Path, scenario: str, duration: float, commands: dict[float, object], monkeypatch) -> Path:
    """Fly ``scenario`` with ground-station ``commands`` ({sim time [s]: command}) applied to its
    first vehicle at the log ticks they are due, as the MAVLink session applies them."""
    from sim import world as world_mod

    worlds = []
    schedule = world_mod.World.schedule
    monkeypatch.setattr(world_mod.World, "schedule", lambda self, sched: (worlds.append(self), schedule(self, sched)))
    due = sorted(commands.items(), key=lambda kv: kv[0])

    def hook(t: float) -> None:
        while due and due[0][0] <= t + 1e-9:
            worlds[0].vehicles[0].apply_command(due.pop(0)[1], t)

    sc, text = load_scenario(SCENARIOS / scenario)
    path = tmp_path / "run.mcap"
    run_scenario(sc, path, scenario_text=text, duration=duration, tick_hook=hook)
    assert not due
    return path


def test_rerun_reproduces_every_plan_across_ground_station_mode_changes(tmp_path, monkeypatch):
    """HOLD, back to AUTO (a fresh mission planner), a new mission uploaded, GUIDED with a
    position target and AUTO again: the scenario's planner re-run on the log makes every plan
    the run made, including those of the planners built by the mode changes."""
    from sim.geodesy import GeoPoint, ned_to_geodetic
    from sim.mavlink.commands import MissionUpload, PositionTarget, SetMode

    lat, lon, alt = ned_to_geodetic(np.array([[90.0, -15.0, -25.0]]), GeoPoint(47.0, 8.0, 400.0))
    upload = MissionUpload(tuple(zip(lat.tolist(), lon.tolist(), alt.tolist(), strict=True)))
    target = PositionTarget(0, np.array([40.0, -10.0, -25.0]), None, None, None)
    commands = {4.0: SetMode("HOLD"), 7.0: SetMode("AUTO"), 11.0: upload, 15.0: SetMode("GUIDED"), 16.0: target}
    commands[19.0] = SetMode("AUTO")
    path = _fly_commanded(tmp_path, "geometric/s3b_moving_main.toml", 25.0, commands, monkeypatch)
    log = RunLog(path)
    events = [text for _, text in log.events()]
    assert {"quad: mode HOLD", "quad: mode AUTO", "quad: mode GUIDED"} <= set(events)
    assert any(text.startswith("quad: mission uploaded") for text in events)
    inputs = log.topic("/quad/plan/input").messages
    assert len({m["planner"] for m in inputs}) == 3  # the scenario's, HOLD's and GUIDED's
    own = [m for m in inputs if m["planner"] == "geometric"]
    built = [m["t"] for m in own if "mission_setup" in m]
    assert built == [0.0, 7.0, 11.0, 19.0]  # the start, AUTO, the upload, AUTO
    made = [m["t"] for m in own if m["new_plan"]]
    assert any(t > 19.0 for t in made)
    modes = [m for m in inputs if m["planner"] != "geometric"]
    assert [(m["t"], m["planner"]) for m in modes if "mode_setup" in m] == [
        (4.0, "hold"),
        (15.0, "hold"),
        (16.0, "goto"),
    ]
    assert [m for m in modes if "mode_setup" in m][-1]["mode_setup"]["target"] == [40.0, -10.0, -25.0]
    mode_made = sum(m["new_plan"] for m in modes)
    rep = rerun_planner(path, "quad")
    assert rep.differences == []
    assert rep.plans == rep.same == len(made) + mode_made  # every plan of the run, HOLD's and GUIDED's too
    assert rep.mode_plans == mode_made > 0


def test_a_rules_planner_rebuilt_by_a_mode_change_joins_the_utm_authority(tmp_path, monkeypatch):
    """S9 under the authority, uas1 put in HOLD at 12 s and back to AUTO at 16 s (a new rules
    planner): the new planner is registered with the authority and gets its directives; while
    the HOLD planner flies, uas1 obeys and acknowledges nothing; and the re-run, which joins
    its rebuilt planner the same way, reproduces every plan of the scenario's planner."""
    from sim import world as world_mod
    from sim.mavlink.commands import SetMode

    worlds: list = []
    schedule = world_mod.World.schedule
    monkeypatch.setattr(world_mod.World, "schedule", lambda self, sched: (worlds.append(self), schedule(self, sched)))
    commands = {12.0: SetMode("HOLD"), 16.0: SetMode("AUTO")}
    path = _fly_commanded(tmp_path, "rules/s9_converging_utm.toml", 24.0, commands, monkeypatch)
    planner = worlds[0].vehicles[0].planner
    assert planner.utm is not None, "the rebuilt rules planner never joined the authority"
    assert planner.utm.received_t is not None and planner.utm.received_t > 16.0
    log = RunLog(path)
    acks = [m["t"] for m in log.topic("/utm/ack").messages if m["from"] == "uas1"]
    assert any(t < 12.0 for t in acks) and any(t > 17.0 for t in acks)
    assert not [t for t in acks if 12.5 < t < 16.0]  # in HOLD: nothing acknowledged (0.2 s link latency)
    own = [m for m in log.topic("/uas1/plan/input").messages if m["planner"] != "hold"]
    assert [m["t"] for m in own if "mission_setup" in m] == [0.0, 16.0]
    rep = rerun_planner(path, "uas1")
    assert rep.differences == []
    inputs = log.topic("/uas1/plan/input").messages
    assert rep.plans == rep.same == sum(m["new_plan"] for m in inputs) > sum(m["new_plan"] for m in own) > 0
    assert rep.mode_plans == sum(m["new_plan"] for m in inputs if m["planner"] == "hold") > 0


def test_a_rerun_plan_with_other_commanded_airspeeds_differs():
    """The re-run's plan equals the recorded one only with the same commanded airspeeds (an MPTP
    hold at V_cor), vertices and times being equal."""
    pos, times, labels = np.zeros((2, 3)), np.array([0.0, 60.0]), np.array([-1, -1])
    rec = {"status": "ok", "positions": pos.tolist(), "times": times.tolist(), "labels": [-1, -1]}
    held = {**rec, "airspeeds": [26.68, 26.68]}
    cases = [
        (rec, None, []),
        (held, np.array([26.68, 26.68]), []),
        (held, np.array([26.68, 27.38]), ["commanded airspeeds differ"]),
        (held, None, ["commanded airspeeds differ"]),
        (rec, np.array([26.68, 26.68]), ["commanded airspeeds differ"]),
    ]
    for recorded, speeds, why in cases:
        new = Plan(0.0, pos, times, labels, airspeeds=speeds)
        assert rerun._differences(rerun.RerunReport("haps", "mptp"), recorded, new) == why
