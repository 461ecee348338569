"""Closed loop: the HAPS flies the box mission; everything is read back from the MCAP it wrote."""

import itertools
import math
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from aircraft.haps.autopilot import HapsGains
from sim.mcap_read import read_info, read_topic
from sim.runner import RunFailed, run_scenario
from sim.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "haps_box_mission.toml"
pytestmark = pytest.mark.closed_loop


@pytest.fixture(scope="module")
def box_run(fly_in, tmp_path_factory):
    run = fly_in(tmp_path_factory.mktemp("box"), "haps_box_mission", "box")
    return run.scenario, run.result, run.path


# 75 min of flight: in CI the HAPS's box tracking to completion is checked on the 4 km box in wind
# and turbulence (test_closed_loop_estimates.py), the waypoint events on quadrotor missions
# (test_mavlink_live.py, test_geometric_closed_loop.py)
@pytest.mark.slow
def test_box_mission_completes_with_tight_tracking(box_run):
    scenario, result, path = box_run
    assert result.status == "completed", result
    assert result.missions["haps"].complete
    wps = scenario.vehicle[0].mission.waypoints
    legs = [math.hypot(b.north - a.north, b.east - a.east) for a, b in itertools.pairwise(wps)]
    assert min(legs) >= 20_000
    assert all(18_000 <= w.altitude <= 20_000 for w in wps)

    states = read_topic(path, "/haps/truth/state")
    sps = read_topic(path, "/haps/ctrl/setpoint")
    assert len(states) == len(sps) > 1000
    st = {k: np.array([m[k] for _, m in states]) for k in ("t", "alt_msl_m", "tas_mps")}
    euler = np.array([m["euler"] for _, m in states])
    assert np.isfinite(euler).all() and np.isfinite(st["alt_msl_m"]).all()
    turning = np.array([m["turning"] for _, m in sps])
    alt_cmd = np.array([m["altitude_m"] for _, m in sps])
    tas_cmd = np.array([m["tas_mps"] for _, m in sps])
    # straight flight: not capturing a leg, and 60 s past the last capture (let transients settle)
    settled = np.zeros_like(turning)
    last_turn = -math.inf
    for i, (t, turn) in enumerate(zip(st["t"], turning, strict=False)):
        if turn:
            last_turn = t
        settled[i] = (not turn) and t - last_turn >= 60.0
    assert settled.mean() > 0.6  # most of the mission is straight flight
    alt_err = np.abs(st["alt_msl_m"] - alt_cmd)[settled]
    tas_err = np.abs(st["tas_mps"] - tas_cmd)[settled]
    assert alt_err.max() <= 50.0, alt_err.max()
    assert tas_err.max() <= 2.0, tas_err.max()
    roll_limit = HapsGains.load().roll_limit_rad
    assert np.abs(euler[:, 0]).max() <= roll_limit + math.radians(2.0)

    events = [m.message for _, m in read_topic(path, "/log")]
    assert [e for e in events if "waypoint" in e] == [f"haps: waypoint {k}/4 reached" for k in range(1, 5)]
    assert "haps: mission complete" in events
    info = read_info(path)
    assert info.metadata["result"]["status"] == "completed"
    assert info.attachments == ["scenario.toml"]
    topics = {t.topic: t.schema for t in info.topics}
    assert topics["/haps/truth/location"] == "foxglove.LocationFix"
    assert topics["/tf"] == "foxglove.FrameTransforms"
    assert topics["/log"] == "foxglove.Log"


def _payloads(path: Path) -> dict[str, list[tuple[int, bytes]]]:
    out: dict[str, list[tuple[int, bytes]]] = defaultdict(list)
    with open(path, "rb") as f:
        for _, channel, msg in make_reader(f).iter_messages(log_time_order=True):
            if channel.metadata.get("wallclock") != "true":
                out[channel.topic].append((msg.log_time, msg.data))
    return out


def test_same_seed_same_payloads(fly):
    a = fly("haps_box_mission", "a", duration=60.0)
    b = fly("haps_box_mission", "b", duration=60.0)
    pa, pb = _payloads(a.path), _payloads(b.path)
    assert len(pa["/haps/truth/state"]) == 601
    assert pa == pb


@pytest.mark.parametrize(
    "exc,status", [(RuntimeError("injected fault"), "failed"), (KeyboardInterrupt(), "interrupted")]
)
def test_run_killed_midway_leaves_log_to_last_tick(tmp_path, exc, status):
    scenario, text = load_scenario(SCENARIO)
    path = tmp_path / "killed.mcap"

    def hook(t):
        if t >= 30.0:
            raise exc

    if status == "failed":
        with pytest.raises(RunFailed, match="injected fault") as info:
            run_scenario(scenario, path, scenario_text=text, tick_hook=hook)
        result = info.value.result
    else:
        result = run_scenario(scenario, path, scenario_text=text, tick_hook=hook)
    assert result.status == status
    states = read_topic(path, "/haps/truth/state")
    assert states[-1][0] == pytest.approx(30.0) and states[-1][1]["t"] == pytest.approx(30.0)
    assert len(states) == 301
    assert read_info(path).metadata["result"]["status"] == status
    assert read_topic(path, "/log")[-1][1].message.startswith(f"run ended: {status}")


def test_cli_run_and_info(tmp_path, cosim):
    log = tmp_path / "cli.mcap"
    run = cosim("run", SCENARIO, "-o", log, "--duration", "20")
    assert run.returncode == 0, run.stderr
    for word in ("duration_elapsed", "real-time factor", "mission haps", "0/4 waypoints", str(log)):
        assert word in run.stdout
    info = cosim("info", log)
    assert info.returncode == 0, info.stderr
    assert "/haps/truth/state" in info.stdout and "haps_box_mission" in info.stdout
