"""Crashes in closed loop, read from the MCAP: a motor failure, a building, two vehicles flown into
each other end in a ``crash`` event and status ``crashed``; a normal landing does not."""

import copy
import math

import numpy as np
import pytest

from aircraft.registry import get_airframe
from sim.core.constants import STANDARD_GRAVITY as G0

pytestmark = pytest.mark.closed_loop

QUAD = get_airframe("quadrotor")
# seeds flown: a few in CI, the 20 of the evidence standard in the slow run
SEEDS = [range(4), pytest.param(range(20), marks=pytest.mark.slow)]


def crashes(flight) -> list[dict]:
    log = flight.log
    return list(log.topic("/world/crash").messages) if log.has("/world/crash") else []


def crash_events(flight) -> list[str]:
    return [text for _, text in flight.log.events() if ": crash: " in text]


@pytest.mark.parametrize("seeds", SEEDS, ids=["4seeds", "20seeds"])
def test_motor_failure_at_30m_falls_with_finite_states_until_it_crashes(fly, scenario_data, seeds):
    base = scenario_data("quad_motor_failure")
    speeds = []
    for seed in seeds:
        data = copy.deepcopy(base) | {"seed": seed}
        f = fly(data, name=f"mf{seed}")
        assert f.result.status == "crashed", (seed, f.result.status, f.result.error)
        assert f.log.metadata["result"]["status"] == "crashed"
        truth = f.log.topic("/quad/truth/state")
        for field in ("pos_ned", "vel_ned", "euler", "rates_body"):
            assert np.isfinite(truth[field]).all(), (seed, field)
        (c,) = crashes(f)
        assert (c["vehicle"], c["kind"], c["hit"]) == ("quad", "ground", "ground")
        assert crash_events(f) == [f"quad: crash: hit the ground at {c['impact_speed_mps']:.2f} m/s"]
        # the run ends at the first contact check after the impact (JSBSim's clock: 1e-9 s rounding)
        assert 2.0 < c["t"] < f.result.sim_time_s + 1e-9 < c["t"] + 1.0 / QUAD.control_hz
        assert abs(c["pos_ned"][2]) < 0.5  # at the ground (CG within the hull's reach)
        speeds.append(c["impact_speed_mps"])
    speeds = np.array(speeds)
    # a fall from 30 m: faster than the gear takes, slower than a drag-free fall (24.3 m/s: drag
    # and the tumbling rotors' thrust brake it; a contact that springs it back up would not)
    assert np.isfinite(speeds).all() and (speeds > QUAD.crash_sink_mps).all()
    assert (speeds < math.sqrt(2 * G0 * 30.0)).all(), speeds


def test_quadrotor_flown_into_a_building_crashes_naming_it(fly, scenario_data):
    data = scenario_data("reachset/building")
    data["obstacle"][0] |= {"id": "tower_b", "north": 30}
    del data["vehicle"][0]["planner"]  # follow the mission straight through the building
    f = fly(data, duration=20.0)
    assert f.result.status == "crashed"
    (c,) = crashes(f)
    assert (c["vehicle"], c["kind"], c["hit"]) == ("quad", "obstacle", "tower_b")
    # the box (20 m, turned 45 deg) reaches 30 - 10 sqrt(2) m north; the sphere touches at r before it
    assert c["pos_ned"][0] == pytest.approx(30 - 10 * math.sqrt(2) - QUAD.radius_m, abs=0.5)
    assert 3.0 < c["impact_speed_mps"] < 7.0  # flying its 5 m/s cruise
    assert crash_events(f) == [f"quad: crash: hit obstacle 'tower_b' at {c['impact_speed_mps']:.2f} m/s"]


def head_on(scenario_data, offset_east: float) -> dict:
    """Two quadrotors on one line (or ``offset_east`` [m] apart), flying at each other. Ideal
    estimates: on the EKF their GNSS-level position errors (about 1 m) decide whether two 0.45 m
    spheres meet (4 seeds: closest 1.1-3.7 m), which is not what this tests."""
    data = scenario_data("reachset/building")
    del data["obstacle"]
    quad = data["vehicle"][0] | {"estimator": "perfect"}
    del quad["planner"]
    a = copy.deepcopy(quad) | {"name": "north_bound"}
    b = copy.deepcopy(quad) | {"name": "south_bound"}
    a["mission"]["waypoints"] = [{"north": 60, "east": 0, "altitude": 420}]
    b["initial"] |= {"north": 40, "east": offset_east, "heading": 180}
    b["mission"]["waypoints"] = [{"north": -20, "east": offset_east, "altitude": 420}]
    data["vehicle"] = [a, b]
    return data


def test_two_vehicles_flown_into_each_other_both_crash(fly, scenario_data):
    f = fly(head_on(scenario_data, 0.0), duration=20.0)
    assert f.result.status == "crashed"
    got = sorted((c["vehicle"], c["kind"], c["hit"]) for c in crashes(f))
    assert got == [("north_bound", "vehicle", "south_bound"), ("south_bound", "vehicle", "north_bound")]
    c = crashes(f)[0]
    assert 6.0 < c["impact_speed_mps"] < 14.0  # closing at about twice the 5 m/s cruise
    a, b = (np.array(c["pos_ned"]) for c in crashes(f))
    assert np.linalg.norm(a - b) < 2 * QUAD.radius_m + c["impact_speed_mps"] / QUAD.control_hz  # one check's closing


def test_two_vehicles_passing_3m_apart_do_not_crash(fly, scenario_data):
    f = fly(head_on(scenario_data, 3.0), duration=14.0)
    assert f.result.status != "crashed" and crashes(f) == []


@pytest.mark.parametrize("seeds", SEEDS, ids=["4seeds", "20seeds"])
def test_normal_landing_is_not_a_crash(fly, scenario_data, seeds):
    data = scenario_data("quad_motor_failure")
    del data["fault"]
    data["vehicle"][0]["initial"]["altitude"] = 405.0
    data["vehicle"][0]["mission"] |= {"land": True, "waypoints": [{"north": 0, "east": 0, "altitude": 405}]}
    data["stop_when_complete"] = True
    for seed in seeds:
        f = fly(data | {"seed": seed}, name=f"land{seed}")
        assert f.result.status == "completed", (seed, f.result.status, f.result.error)
        assert crashes(f) == [] and crash_events(f) == []
        assert any(text == "quad: landed" for _, text in f.log.events())
        down = f.log.topic("/quad/truth/state")["pos_ned"][:, 2]
        assert down[-1] > -0.3  # it is on the ground (CG 0.15 m above it on the gear)


def test_cli_run_of_a_crash_exits_1_and_its_log_reads(cosim, tmp_path):
    log = tmp_path / "crash.mcap"
    run = cosim("run", "scenarios/quad_motor_failure.toml", "-o", log, "-q")
    assert run.returncode == 1, run.stderr
    assert "crashed" in run.stdout and "hit the ground" in run.stdout
    info = cosim("info", log)
    assert info.returncode == 0 and "crashed" in info.stdout and "/world/crash" in info.stdout
    replay = cosim("replay", log, "-o", tmp_path / "report")
    assert replay.returncode == 0, replay.stderr
    report = (tmp_path / "report" / "report.md").read_text()
    assert "result: **crashed**" in report and "quad: crash: hit the ground at" in report
