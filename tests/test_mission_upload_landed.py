"""A mission uploaded to a multirotor still on the ground is flown, and a GUIDED position target
is flown to, whenever the command arrives (sim/vehicle_commands.py). A ground station fast
enough to finish an upload in the first tick (it happened in CI under load) met a vehicle whose
first estimate carries its alignment error (metres off, below the ground): the first leg started
there, the setpoint stayed on the ground and the vehicle never took off."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

import sim.runner as runner
from sim.geodesy import ned_to_geodetic
from sim.mavlink.commands import MissionUpload, PositionTarget, SetMode
from sim.replay.runlog import RunLog
from sim.scenario import parse_scenario

ROOT = Path(__file__).resolve().parents[1]
TARGETS = [[20.0, 0.0, -15.0], [20.0, 20.0, -15.0], [0.0, 20.0, -15.0]]  # NED [m]


def _fly_commanded(tmp_path, monkeypatch, at_t: float, commands) -> RunLog:
    """quad_square_mission on the ground, its own mission a hover that only a command ends;
    ``commands(vehicle, t)`` applied at sim time ``at_t`` [s]; 60 s at most."""
    data = tomllib.loads((ROOT / "scenarios" / "quad_square_mission.toml").read_text())
    data.update(duration=60.0, stop_when_complete=True)
    v = data["vehicle"][0]
    assert v["initial"].get("on_ground", False)
    v["mission"]["land"] = False
    v["mission"]["waypoints"] = [{"north": 0, "east": 0, "altitude": 415, "hold": "1000 s"}]
    worlds: list = []

    class World(runner.World):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            worlds.append(self)

    monkeypatch.setattr(runner, "World", World)

    def hook(t: float) -> None:
        if t == at_t:
            commands(worlds[0].vehicles[0], t)

    runner.run_scenario(parse_scenario(data, "commanded"), tmp_path / "c.mcap", tick_hook=hook)
    return RunLog(tmp_path / "c.mcap")


@pytest.mark.closed_loop
@pytest.mark.parametrize("at_t", [0.0, 0.5])
def test_a_mission_uploaded_to_a_landed_multirotor_is_flown(tmp_path, monkeypatch, at_t):
    def upload(vehicle, t):
        lat, lon, alt = ned_to_geodetic(TARGETS, vehicle.origin)
        vehicle.apply_command(MissionUpload(tuple(zip(lat, lon, alt, strict=True))), t)

    log = _fly_commanded(tmp_path, monkeypatch, at_t, upload)
    assert log.metadata["result"]["status"] == "completed"
    events = [text for _, text in log.events()]
    assert [e for e in events if e.endswith("/3 reached")] == [f"quad: waypoint {k}/3 reached" for k in (1, 2, 3)]


@pytest.mark.closed_loop
@pytest.mark.parametrize("at_t", [0.0, 0.5])
def test_a_guided_target_given_to_a_landed_multirotor_is_flown_to(tmp_path, monkeypatch, at_t):
    def guided(vehicle, t):
        vehicle.apply_command(SetMode("GUIDED"), t)
        vehicle.apply_command(PositionTarget(0, np.array(TARGETS[0]), None, None, None), t)

    log = _fly_commanded(tmp_path, monkeypatch, at_t, guided)
    end = log.topic("/quad/truth/state")["pos_ned"][-1]
    assert np.linalg.norm(end - TARGETS[0]) < 2.0, end
