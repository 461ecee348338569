"""A mission uploaded to a multirotor still on the ground is flown, whenever it arrives
(sim/vehicle_commands.py). A ground station fast enough to finish the upload in the first tick
(it happened in CI under load) met a vehicle whose first estimate carries its alignment error
(metres off, below the ground): the first leg started there, the setpoint stayed on the ground
and the vehicle never took off."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

import sim.runner as runner
from sim.geodesy import ned_to_geodetic
from sim.mavlink.commands import MissionUpload
from sim.replay.runlog import RunLog
from sim.scenario import parse_scenario

ROOT = Path(__file__).resolve().parents[1]
TARGETS = [[20.0, 0.0, -15.0], [20.0, 20.0, -15.0], [0.0, 20.0, -15.0]]  # NED [m]


@pytest.mark.closed_loop
@pytest.mark.parametrize("upload_t", [0.0, 0.5])
def test_a_mission_uploaded_to_a_landed_multirotor_is_flown(tmp_path, monkeypatch, upload_t):
    data = tomllib.loads((ROOT / "scenarios" / "quad_square_mission.toml").read_text())
    data.update(duration=60.0, stop_when_complete=True)
    v = data["vehicle"][0]
    assert v["initial"].get("on_ground", False)
    v["mission"]["land"] = False
    v["mission"]["waypoints"] = [{"north": 0, "east": 0, "altitude": 415, "hold": "1000 s"}]  # only an upload ends it
    scenario = parse_scenario(data, "upload")
    worlds: list = []

    class World(runner.World):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            worlds.append(self)

    monkeypatch.setattr(runner, "World", World)
    lat, lon, alt = ned_to_geodetic(TARGETS, scenario.origin_point)

    def upload(t: float) -> None:
        if t == upload_t:
            worlds[0].vehicles[0].apply_command(MissionUpload(tuple(zip(lat, lon, alt, strict=True))), t)

    result = runner.run_scenario(scenario, tmp_path / "u.mcap", tick_hook=upload)
    assert result.status == "completed", result.sim_time_s
    events = [text for _, text in RunLog(tmp_path / "u.mcap").events()]
    assert [e for e in events if e.endswith("/3 reached")] == [f"quad: waypoint {k}/3 reached" for k in (1, 2, 3)]
