"""Bad scenario files: one line naming the file and the field, exit code 2, no traceback."""

import math
import tomllib
from datetime import UTC, datetime
from pathlib import Path

import pytest
import tomli_w

from sim.runner import run_scenario
from sim.scenario import ScenarioError, load_scenario, parse_scenario

ROOT = Path(__file__).resolve().parents[1]
GOOD = tomllib.loads((ROOT / "scenarios" / "haps_box_mission.toml").read_text())


def _mutate(path: list, value):
    data = tomllib.loads((ROOT / "scenarios" / "haps_box_mission.toml").read_text())
    node = data
    for key in path[:-1]:
        node = node[key]
    if value is _DELETE:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return data


_DELETE = object()

CASES = [
    (
        "unknown_key",
        _mutate(["vehicle", 0, "initial", "altitude_ft"], 59000),
        None,
        "vehicle[0].initial.altitude_ft: unknown key",
    ),
    (
        "wrong_unit",
        _mutate(["vehicle", 0, "mission", "cruise_speed"], "26 km"),
        None,
        "vehicle[0].mission.cruise_speed: wrong unit: 'km' is a length, this field is a speed",
    ),
    (
        "unknown_unit",
        _mutate(["vehicle", 0, "initial", "altitude"], "18 furlong"),
        None,
        "vehicle[0].initial.altitude: unknown unit 'furlong'",
    ),
    (
        "unknown_aircraft",
        _mutate(["vehicle", 0, "aircraft"], "hapz"),
        None,
        "vehicle[0].aircraft: unknown aircraft 'hapz' (known: haps",
    ),
    (
        "missing_field",
        _mutate(["vehicle", 0, "mission", "waypoints"], _DELETE),
        None,
        "vehicle[0].mission.waypoints: missing required field",
    ),
    (
        "out_of_range",
        _mutate(["vehicle", 0, "mission", "waypoints", 2, "altitude"], "45 km"),
        None,
        "vehicle[0].mission.waypoints[2].altitude: out of range: 45000 m not in [-500, 30000] m",
    ),
    ("latitude_range", _mutate(["origin", "lat"], 95.0), None, "origin.lat: out of range: 95 deg not in [-90, 90] deg"),
    ("wrong_type", _mutate(["seed"], "one"), None, "seed: "),
    ("duplicate_names", {**GOOD, "vehicle": GOOD["vehicle"] * 2}, None, "vehicle names must be unique, repeated: haps"),
    (
        "naive_time",
        None,
        'name="x"\nseed=1\nduration=10\nstart_time=2026-06-21T06:00:00\n[origin]\nlat=0\nlon=0\n',
        "start_time: start_time needs a time zone",
    ),
    ("bad_toml", None, 'name = "x\nseed = 1\n', "not valid TOML"),
    (
        "fault_vehicle",
        {**GOOD, "fault": [{"vehicle": "hapz", "kind": "gust", "at": 10, "east": 3}]},
        None,
        "fault[0].vehicle: no vehicle 'hapz' (vehicles: haps)",
    ),
    (
        "stop_vehicle",
        {**GOOD, "stop_when_complete": ["haps", "hapz"]},
        None,
        "stop_when_complete[1]: no vehicle 'hapz' (vehicles: haps)",
    ),
    (
        "fault_kind",
        {**GOOD, "fault": [{"vehicle": "haps", "kind": "lightning", "at": 10}]},
        None,
        "fault[0].kind: unknown kind 'lightning' (known: 'gnss_loss', 'sensor_bias'",
    ),
    (
        "obstacle_fields",
        {**GOOD, "obstacle": [{"id": "t", "shape": "cylinder", "top": 500}]},
        None,
        "obstacle[0]: radius: a cylinder needs radius",
    ),
    (
        "crossed_polygon",
        {**GOOD, "geofence": [{"id": "g", "points": [[0, 0], [1, 1], [1, 0], [0, 1]]}]},
        None,
        "geofence[0].points: points: the polygon is not simple (its edges cross)",
    ),
    ("turbulence", {**GOOD, "wind": {"turbulence": "extreme"}}, None, "wind.turbulence: Input should be 'none'"),
    (
        "obstacle_top_below_base",
        {**GOOD, "obstacle": [{"id": "t", "shape": "cylinder", "radius": 5, "base": 300, "top": 200}]},
        None,
        "obstacle[0]: top: 200 m is not above its base 300 m",
    ),
    (
        "obstacle_below_ground",
        {
            **GOOD,
            "origin": {**GOOD["origin"], "altitude": 400},
            "obstacle": [{"id": "t", "shape": "cylinder", "radius": 5, "top": 350}],
        },
        None,
        "obstacle[0].top: 350 m is not above the ground (400 m, origin altitude)",
    ),
    (
        "start_below_ground",
        {
            **_mutate(["origin", "altitude"], 1000),
            "vehicle": [{**GOOD["vehicle"][0], "initial": {**GOOD["vehicle"][0]["initial"], "altitude": 900}}],
        },
        None,
        "vehicle[0].initial.altitude: 900 m is below the ground (1000 m, origin altitude)",
    ),
    (
        "waypoint_below_ground",
        _mutate(["vehicle", 0, "mission", "waypoints", 1, "altitude"], -10),
        None,
        "vehicle[0].mission.waypoints[1].altitude: -10 m is below the ground (0 m, origin altitude)",
    ),
    (
        "start_above_ceiling",
        _mutate(["vehicle", 0, "initial", "altitude"], "24 km"),
        None,
        "vehicle[0].initial.altitude: 24000 m is above the haps ceiling (23000 m MSL)",
    ),
    (
        "waypoint_above_ceiling",
        _mutate(["vehicle", 0, "mission", "waypoints", 2, "altitude"], "24 km"),
        None,
        "vehicle[0].mission.waypoints[2].altitude: 24000 m is above the haps ceiling (23000 m MSL)",
    ),
    (
        "cruise_below_eas_envelope",
        _mutate(["vehicle", 0, "mission", "cruise_speed"], "20 m/s"),
        None,
        "vehicle[0].mission.cruise_speed: 20 m/s TAS is EAS 6.30 m/s at waypoints[0] (18000 m), outside the "
        "haps envelope EAS 7.3-12 m/s (TAS 23.2-38.1 m/s there)",
    ),
    (
        "cruise_above_eas_envelope",
        _mutate(["vehicle", 0, "mission", "cruise_speed"], "45 m/s"),
        None,
        "vehicle[0].mission.cruise_speed: 45 m/s TAS is EAS 14.18 m/s at waypoints[0] (18000 m)",
    ),
    (
        "start_before_log_epoch",
        {**GOOD, "start_time": datetime(1969, 12, 31, 23, tzinfo=UTC)},
        None,
        "start_time: the run (1969-12-31T23:00:00Z + duration) must lie between 1970-01-01 and 2554-07-21",
    ),
    (
        "run_ends_after_log_times",
        {**GOOD, "start_time": datetime(2554, 7, 21, 23, tzinfo=UTC)},
        None,
        "start_time: the run (2554-07-21T23:00:00Z + duration) must lie between 1970-01-01 and 2554-07-21",
    ),
    (
        "fixed_wing_land",
        _mutate(["vehicle", 0, "mission", "land"], True),
        None,
        "vehicle[0]: mission.land: only multirotors land at the end of a mission (haps is fixed_wing)",
    ),
]


@pytest.mark.parametrize("kind,data,text,expected", CASES, ids=[c[0] for c in CASES])
def test_bad_scenario_is_one_line_error_exit_2(tmp_path, capsys, monkeypatch, kind, data, text, expected):
    """``cosim run`` in this process (its ``main``, exactly what the console script calls; the
    other tests of this file run it as a separate process)."""
    from sim.cli import main

    f = tmp_path / f"{kind}.toml"
    f.write_text(text if text is not None else tomli_w.dumps(data))
    monkeypatch.chdir(tmp_path)
    code = main(["run", str(f), "-q"])
    stderr = capsys.readouterr().err
    assert code == 2, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    assert "Traceback" not in stderr
    assert lines[0].startswith(f"error: {f}: ")
    assert expected in lines[0]
    assert not (tmp_path / "logs").exists()


def test_missing_file_is_exit_2(tmp_path, cosim):
    proc = cosim("run", tmp_path / "nope.toml")
    assert proc.returncode == 2
    assert "cannot read scenario file" in proc.stderr and "Traceback" not in proc.stderr


def test_unwritable_log_path_is_exit_2(tmp_path, cosim):
    proc = cosim("run", "scenarios/quad_hover_offset.toml", "-o", tmp_path)
    assert proc.returncode == 2
    assert "cannot write the log" in proc.stderr and "Traceback" not in proc.stderr


def test_good_scenario_validates(cosim):
    proc = cosim("validate", "scenarios/haps_box_mission.toml")
    assert proc.returncode == 0, proc.stderr


@pytest.mark.parametrize("value", ["0", "-5", "nan", "inf", "ten"])
def test_bad_duration_option_is_exit_2(cosim, value):
    proc = cosim("run", "scenarios/quad_hover_offset.toml", f"--duration={value}", "-q")
    assert proc.returncode == 2
    assert "argument --duration:" in proc.stderr and "Traceback" not in proc.stderr


def test_quadrotor_waypoint_above_its_ceiling_is_refused():
    data = tomllib.loads((ROOT / "scenarios" / "quad_hover_offset.toml").read_text())
    data["vehicle"][0]["mission"]["waypoints"][0]["altitude"] = 7900.0
    with pytest.raises(ScenarioError, match=r"^q: vehicle\[0\]\.mission\.waypoints\[0\]\.altitude: 7900 m is above "):
        parse_scenario(data, "q")
    data["vehicle"][0]["mission"]["waypoints"][0]["altitude"] = 7800.0  # T/W 2.02 there (ISA)
    parse_scenario(data, "q")


@pytest.mark.parametrize("value", [0.0, -5.0, math.nan, math.inf])
def test_bad_duration_to_the_runner_is_refused_before_the_log(tmp_path, value):
    sc, _ = load_scenario(ROOT / "scenarios" / "quad_hover_offset.toml")
    with pytest.raises(ValueError, match=r"^duration: must be a finite number of seconds > 0"):
        run_scenario(sc, tmp_path / "x.mcap", duration=value)
    assert not (tmp_path / "x.mcap").exists()
