"""No silent field: every field of the scenario schema acts on the run's log, or is a label.

The walk covers the whole schema (nested sections, every member of a tagged union, the planner
types' options from the registry). Each field must be in exactly one of:

- ``EFFECTS``: a change of the field, applied to a short baseline run (3 s of sim time, ideal
  sensors unless the field is a sensor's), must change the MCAP log (some channel's messages);
- ``LABELS``: names and tags that only identify things;
- ``SHOWN_ELSEWHERE``: fields whose effect needs more than a short run, with the test that shows it;
- ``NOT_YET_SHOWN``: fields no test shows acting yet (issue 15 work list; must only shrink).

A new schema field fails ``test_every_field_is_accounted_for`` until it is placed.
"""

from __future__ import annotations

import copy
import importlib.util
import typing
from collections.abc import Callable
from pathlib import Path

import pytest
import tomli_w
from pydantic import BaseModel

from sim import scenario as sc
from sim.runner import run_scenario

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("compare_log_payloads", ROOT / "scripts" / "compare_log_payloads.py")
_compare = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_compare)


def _models(annotation: object) -> list[type[BaseModel]]:
    """The pydantic models inside an annotation (through lists, optionals, unions, Annotated)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for a in typing.get_args(annotation) for m in _models(a)]


def schema_fields(model: type[BaseModel] = sc.Scenario, prefix: str = "") -> list[str]:
    """Dotted paths of every leaf field; a union member's fields are ``path<Model>.field``."""
    out = []
    for name, field in model.model_fields.items():
        path = f"{prefix}.{name}" if prefix else name
        subs = _models(field.annotation)
        for m in subs:
            out += schema_fields(m, f"{path}<{m.__name__}>" if len(subs) > 1 else path)
        if not subs:
            out.append(path)
    return out


# --- the baselines: short runs with every optional section present --------------------------

_QUAD = {
    "name": "silent_quad",
    "seed": 5,
    "duration": 3.0,
    "stop_when_complete": False,
    "origin": {"lat": 47.0, "lon": 8.0, "altitude": 400.0},
    "logging": {"rate_hz": 10},
    "surveillance": {"rate_hz": 5},
    "object": [
        {"id": "kite", "radius": 2.0, "north": 30.0, "east": 5.0, "altitude": 420.0, "velocity": {"north": -1.0}}
    ],
    "obstacle": [{"id": "mast", "shape": "box", "north": 8.0, "east": 0.0, "length": 2.0, "width": 8.0, "top": 440.0}],
    "geofence": [
        {"id": "zone", "points": [[-50, -50], [-50, 50], [50, 50], [50, -50]], "floor": 300.0, "ceiling": 600.0}
    ],
    "fault": [
        {"vehicle": "quad", "kind": "gust", "at": 1.0, "duration": 1.0, "east": 3.0, "ramp": 0.5},
        {"vehicle": "quad", "kind": "motor_failure", "at": 2.8, "duration": 0.1, "engine": 0},
    ],
    "vehicle": [
        {
            "name": "quad",
            "aircraft": "quadrotor",
            "estimator": "perfect",
            "lidar": {"rate_hz": 5},
            "initial": {"altitude": 420.0},
            "mission": {
                "cruise_speed": 4.0,
                "acceptance_radius": 1.0,
                "waypoints": [
                    {"north": 3.0, "east": 0.0, "altitude": 421.0, "hold": 1.0, "yaw": 10.0},
                    {"north": 3.0, "east": 6.0, "altitude": 421.0},
                ],
            },
        }
    ],
}

_HAPS = {
    "name": "silent_haps",
    "seed": 5,
    "duration": 3.0,
    "origin": {"lat": 47.0, "lon": 8.0, "altitude": 0.0},
    "logging": {"rate_hz": 10},
    "vehicle": [
        {
            "name": "haps",
            "aircraft": "haps",
            "estimator": "perfect",
            "initial": {"altitude": 18000.0, "airspeed": 26.0},
            "mission": {"cruise_speed": 26.0, "waypoints": [{"north": 20000.0, "east": 2000.0, "altitude": 18000.0}]},
        }
    ],
}

_WEATHER = {"cells": 4, "size": 20000.0, "radius": 2000.0, "nowcast_period": 10.0, "horizon": 60.0, "step": 10.0}
_LEVELS = [{"altitude": 0.0, "north": 1.0, "east": 2.0}, {"altitude": 1000.0, "north": 3.0, "east": 4.0}]
_HOURS = [{"time": 0.0, "levels": _LEVELS}, {"time": 2.0, "levels": [dict(lv, east=-4.0) for lv in _LEVELS]}]


def _quad(d: dict) -> dict:
    return d["vehicle"][0]


def _set(path: str, value: object) -> Callable[[dict], None]:
    """A change that sets the dotted ``path`` (list items as ``name.0``) to ``value``."""

    def change(d: dict) -> None:
        *head, last = path.split(".")
        node: typing.Any = d
        for part in head:
            node = node[int(part)] if part.isdigit() else node.setdefault(part, {})
        node[last] = value

    return change


def _fault(kind: str, **values: object) -> Callable[[dict], None]:
    def change(d: dict) -> None:
        next(f for f in d["fault"] if f["kind"] == kind).update(values)

    return change


_SENSOR_FAULTS = [
    {"vehicle": "quad", "kind": "sensor_bias", "at": 1.0, "duration": 1.0, "sensor": "baro", "bias": 2.0},
    {"vehicle": "quad", "kind": "sensor_stuck", "at": 1.0, "duration": 1.0, "sensor": "mag"},
    {"vehicle": "quad", "kind": "gnss_loss", "at": 1.5, "duration": 1.0},
]


def _on_ekf_with_sensor_faults(d: dict) -> None:
    """Sensor faults act on sensor models: the EKF, with one fault of each sensor kind."""
    _quad(d)["estimator"] = "ekf"
    d["fault"] = d["fault"] + copy.deepcopy(_SENSOR_FAULTS)


def _near_start_mission(d: dict) -> None:
    """One waypoint at the start: the mission completes at once."""
    _quad(d)["mission"].update(waypoints=[{"north": 0.0, "east": 0.0, "altitude": 420.0}], acceptance_radius=2.0)


def _weather_for(duration: float) -> Callable[[dict], None]:
    """The weather section and a run long enough for a second nowcast."""

    def prepare(d: dict) -> None:
        d.update(weather=copy.deepcopy(_WEATHER), duration=duration)

    return prepare


def _gains(d: dict, tmp: Path) -> None:
    text = (ROOT / "aircraft" / "quadrotor" / "gains.toml").read_text().replace("kp_xy = 0.95", "kp_xy = 0.5")
    (tmp / "gains.toml").write_text(text)
    _quad(d)["gains"] = str(tmp / "gains.toml")


_QUAD_MISSION_HIGH = {"cruise_speed": 4.0, "waypoints": [{"north": 5.0, "east": 0.0, "altitude": 18000.0}]}

# (baseline, preparation applied to both runs or None, the change)
Effect = tuple[dict, Callable[[dict], None] | None, Callable[..., None]]

EFFECTS: dict[str, Effect] = {
    "seed": (_QUAD, _set("vehicle.0.estimator", "ekf"), _set("seed", 6)),
    "duration": (_QUAD, None, _set("duration", 2.0)),
    "start_time": (_QUAD, None, _set("start_time", "2026-06-21T07:00:00Z")),
    "stop_when_complete": (_QUAD, _near_start_mission, _set("stop_when_complete", True)),
    "origin.lat": (_QUAD, None, _set("origin.lat", 47.1)),
    "origin.lon": (_QUAD, None, _set("origin.lon", 8.1)),
    "origin.altitude": (_QUAD, None, _set("origin.altitude", 410.0)),
    "logging.rate_hz": (_QUAD, None, _set("logging.rate_hz", 20)),
    "logging.encoding": (_QUAD, None, _set("logging.encoding", "json")),
    "wind.north": (_QUAD, None, _set("wind.north", 2.0)),
    "wind.east": (_QUAD, None, _set("wind.east", 2.0)),
    "wind.down": (_QUAD, None, _set("wind.down", 0.5)),
    "wind.turbulence": (_QUAD, None, _set("wind.turbulence", "light")),
    "wind.levels.altitude": (_QUAD, _set("wind.levels", _LEVELS), _set("wind.levels.1.altitude", 2000.0)),
    "wind.levels.north": (_QUAD, _set("wind.levels", _LEVELS), _set("wind.levels.0.north", -1.0)),
    "wind.levels.east": (_QUAD, _set("wind.levels", _LEVELS), _set("wind.levels.0.east", -1.0)),
    "wind.hours.time": (_QUAD, _set("wind.hours", _HOURS), _set("wind.hours.1.time", 4.0)),
    "wind.hours.levels.altitude": (_QUAD, _set("wind.hours", _HOURS), _set("wind.hours.0.levels.1.altitude", 2e3)),
    "wind.hours.levels.north": (_QUAD, _set("wind.hours", _HOURS), _set("wind.hours.0.levels.0.north", -1.0)),
    "wind.hours.levels.east": (_QUAD, _set("wind.hours", _HOURS), _set("wind.hours.0.levels.0.east", -1.0)),
    "wind.standard": (_QUAD, None, _set("wind.standard", "midlatitude_jet")),
    "surveillance.rate_hz": (_QUAD, None, _set("surveillance.rate_hz", 2.0)),
    "surveillance.latency": (_QUAD, None, _set("surveillance.latency", 0.2)),
    "surveillance.dropout": (_QUAD, None, _set("surveillance.dropout", 0.5)),
    "surveillance.position_noise_horizontal": (_QUAD, None, _set("surveillance.position_noise_horizontal", 9.0)),
    "surveillance.position_noise_vertical": (_QUAD, None, _set("surveillance.position_noise_vertical", 9.0)),
    "surveillance.velocity_noise": (_QUAD, None, _set("surveillance.velocity_noise", 2.0)),
    "weather.cells": (_QUAD, _set("weather", _WEATHER), _set("weather.cells", 5)),
    "weather.size": (_QUAD, _set("weather", _WEATHER), _set("weather.size", 30000.0)),
    "weather.drift_north": (_QUAD, _set("weather", _WEATHER), _set("weather.drift_north", 5.0)),
    "weather.drift_east": (_QUAD, _set("weather", _WEATHER), _set("weather.drift_east", 5.0)),
    "weather.drift_spread": (_QUAD, _set("weather", _WEATHER), _set("weather.drift_spread", 1.0)),
    "weather.radius": (_QUAD, _set("weather", _WEATHER), _set("weather.radius", 3000.0)),
    "weather.split_probability": (_QUAD, _set("weather", _WEATHER), _set("weather.split_probability", 0.9)),
    "weather.life": (_QUAD, _set("weather", _WEATHER), _set("weather.life", 600.0)),
    "weather.nowcast_period": (_QUAD, _weather_for(11.0), _set("weather.nowcast_period", 20.0)),
    "weather.horizon": (_QUAD, _set("weather", _WEATHER), _set("weather.horizon", 120.0)),
    "weather.step": (_QUAD, _set("weather", _WEATHER), _set("weather.step", 20.0)),
    "weather.centres": (_QUAD, _set("weather", _WEATHER), _set("weather.centres", [[1000.0, 1000.0]] * 4)),
    "weather.seed": (_QUAD, _set("weather", _WEATHER), _set("weather.seed", 11)),
    "weather.pop_up": (_QUAD, _set("weather", _WEATHER), _set("weather.pop_up", False)),
    "weather.storm.points": (
        _QUAD,
        _set("weather", _WEATHER | {"storm": [{"points": [[0, 0], [0, 900], [900, 0]]}]}),
        _set("weather.storm.0.points", [[0, 0], [0, 800], [800, 0]]),
    ),
    "weather.storm.drift_north": (
        _QUAD,
        _set("weather", _WEATHER | {"storm": [{"points": [[0, 0], [0, 900], [900, 0]]}]}),
        _set("weather.storm.0.drift_north", 3.0),
    ),
    "weather.storm.drift_east": (
        _QUAD,
        _set("weather", _WEATHER | {"storm": [{"points": [[0, 0], [0, 900], [900, 0]]}]}),
        _set("weather.storm.0.drift_east", 3.0),
    ),
    "object.radius": (_QUAD, None, _set("object.0.radius", 3.0)),
    "object.north": (_QUAD, None, _set("object.0.north", 40.0)),
    "object.east": (_QUAD, None, _set("object.0.east", 10.0)),
    "object.altitude": (_QUAD, None, _set("object.0.altitude", 425.0)),
    "object.velocity.north": (_QUAD, None, _set("object.0.velocity.north", -2.0)),
    "object.velocity.east": (_QUAD, None, _set("object.0.velocity.east", 1.0)),
    "object.velocity.down": (_QUAD, None, _set("object.0.velocity.down", 1.0)),
    "object.appear": (_QUAD, None, _set("object.0.appear", 1.0)),
    "object.cooperative": (_QUAD, None, _set("object.0.cooperative", True)),
    "obstacle.shape": (_QUAD, None, lambda d: d["obstacle"][0].update(shape="cylinder", radius=3.0)),
    "obstacle.north": (_QUAD, None, _set("obstacle.0.north", 9.0)),
    "obstacle.east": (_QUAD, None, _set("obstacle.0.east", 1.0)),
    "obstacle.length": (_QUAD, None, _set("obstacle.0.length", 3.0)),
    "obstacle.width": (_QUAD, None, _set("obstacle.0.width", 9.0)),
    "obstacle.heading": (_QUAD, None, _set("obstacle.0.heading", 30.0)),
    "obstacle.radius": (
        _QUAD,
        lambda d: d["obstacle"][0].update(shape="cylinder", radius=3.0),
        _set("obstacle.0.radius", 4.0),
    ),
    "obstacle.points": (
        _QUAD,
        lambda d: d["obstacle"][0].update(shape="polygon", points=[[7, -4], [7, 4], [9, 0]]),
        _set("obstacle.0.points", [[7, -5], [7, 5], [9, 0]]),
    ),
    "obstacle.base": (_QUAD, None, _set("obstacle.0.base", 415.0)),
    "obstacle.top": (_QUAD, None, _set("obstacle.0.top", 430.0)),
    "geofence.points": (_QUAD, None, _set("geofence.0.points", [[-60, -60], [-60, 60], [60, 60], [60, -60]])),
    "geofence.floor": (_QUAD, None, _set("geofence.0.floor", 350.0)),
    "geofence.ceiling": (_QUAD, None, _set("geofence.0.ceiling", 500.0)),
    "geofence.keep_in": (_QUAD, None, _set("geofence.0.keep_in", False)),
    "fault<GnssLoss>.at": (_QUAD, _on_ekf_with_sensor_faults, _fault("gnss_loss", at=0.5)),
    "fault<GnssLoss>.duration": (_QUAD, _on_ekf_with_sensor_faults, _fault("gnss_loss", duration=0.5)),
    "fault<SensorBias>.at": (_QUAD, _on_ekf_with_sensor_faults, _fault("sensor_bias", at=0.5)),
    "fault<SensorBias>.duration": (_QUAD, _on_ekf_with_sensor_faults, _fault("sensor_bias", duration=0.5)),
    "fault<SensorBias>.sensor": (_QUAD, _on_ekf_with_sensor_faults, _fault("sensor_bias", sensor="gnss")),
    "fault<SensorBias>.bias": (_QUAD, _on_ekf_with_sensor_faults, _fault("sensor_bias", bias=5.0)),
    "fault<SensorStuck>.at": (_QUAD, _on_ekf_with_sensor_faults, _fault("sensor_stuck", at=0.5)),
    "fault<SensorStuck>.duration": (_QUAD, _on_ekf_with_sensor_faults, _fault("sensor_stuck", duration=0.5)),
    "fault<SensorStuck>.sensor": (_QUAD, _on_ekf_with_sensor_faults, _fault("sensor_stuck", sensor="baro")),
    "fault<MotorFailure>.at": (_QUAD, None, _fault("motor_failure", at=2.5)),
    "fault<MotorFailure>.duration": (_QUAD, None, _fault("motor_failure", duration=0.15)),
    "fault<MotorFailure>.engine": (_QUAD, None, _fault("motor_failure", engine=1)),
    "fault<Gust>.at": (_QUAD, None, _fault("gust", at=0.5)),
    "fault<Gust>.duration": (_QUAD, None, _fault("gust", duration=1.5)),
    "fault<Gust>.north": (_QUAD, None, _fault("gust", north=2.0)),
    "fault<Gust>.east": (_QUAD, None, _fault("gust", east=1.0)),
    "fault<Gust>.down": (_QUAD, None, _fault("gust", down=1.0)),
    "fault<Gust>.ramp": (_QUAD, None, _fault("gust", ramp=0.2)),
    "vehicle.aircraft": (
        _HAPS,
        None,
        lambda d: _quad(d).update(aircraft="quadrotor", initial={"altitude": 18000.0}, mission=_QUAD_MISSION_HIGH),
    ),
    "vehicle.gains": (_QUAD, None, _gains),
    "vehicle.estimator": (_QUAD, None, _set("vehicle.0.estimator", "ekf")),
    "vehicle.initial.north": (_QUAD, None, _set("vehicle.0.initial.north", 1.0)),
    "vehicle.initial.east": (_QUAD, None, _set("vehicle.0.initial.east", 1.0)),
    "vehicle.initial.altitude": (_QUAD, None, _set("vehicle.0.initial.altitude", 422.0)),
    "vehicle.initial.airspeed": (_HAPS, None, _set("vehicle.0.initial.airspeed", 27.0)),
    "vehicle.initial.heading": (_QUAD, None, _set("vehicle.0.initial.heading", 20.0)),
    "vehicle.initial.roll": (_QUAD, None, _set("vehicle.0.initial.roll", 5.0)),
    "vehicle.initial.pitch": (_QUAD, None, _set("vehicle.0.initial.pitch", 5.0)),
    "vehicle.initial.trim": (_HAPS, None, _set("vehicle.0.initial.trim", False)),
    "vehicle.initial.on_ground": (_QUAD, None, _set("vehicle.0.initial.on_ground", True)),
    "vehicle.mission.cruise_speed": (_QUAD, None, _set("vehicle.0.mission.cruise_speed", 2.0)),
    "vehicle.mission.acceptance_radius": (_QUAD, None, _set("vehicle.0.mission.acceptance_radius", 2.5)),
    "vehicle.mission.waypoints.north": (_QUAD, None, _set("vehicle.0.mission.waypoints.0.north", 4.0)),
    "vehicle.mission.waypoints.east": (_QUAD, None, _set("vehicle.0.mission.waypoints.0.east", 1.0)),
    "vehicle.mission.waypoints.altitude": (_QUAD, None, _set("vehicle.0.mission.waypoints.0.altitude", 423.0)),
    "vehicle.mission.waypoints.hold": (_QUAD, None, _set("vehicle.0.mission.waypoints.0.hold", 0.0)),
    "vehicle.mission.waypoints.yaw": (_QUAD, None, _set("vehicle.0.mission.waypoints.0.yaw", 90.0)),
    "vehicle.mission.land": (_QUAD, _near_start_mission, _set("vehicle.0.mission.land", True)),
    "vehicle.mission.guidance": (_QUAD, None, _set("vehicle.0.mission.guidance", "step")),
    "vehicle.planner<FollowMissionPlanner>.rate_hz": (_QUAD, None, _set("vehicle.0.planner.rate_hz", 2.0)),
}

_LIDAR = {
    "latency_s": 0.05,
    "max_range_m": 6.0,
    "azimuth_min_deg": -60.0,
    "azimuth_max_deg": -90.0,  # the mast is ahead
    "azimuth_step_deg": 2.0,
    "elevation_min_deg": -10.0,
    "elevation_max_deg": 10.0,
    "elevation_step_deg": 4.0,
    "return_probability": 0.5,
    "dropout": 0.9,
    "range_resolution_m": 0.5,
}
for _k, _v in _LIDAR.items():
    EFFECTS[f"vehicle.lidar.{_k}"] = (_QUAD, None, _set(f"vehicle.0.lidar.{_k}", _v))

# sensor fields act on the EKF baseline (the HAPS for the pitot: a multirotor has none); the
# rates must divide the plant rate (quadrotor 240 Hz, HAPS 120 Hz) and be multiples of the fusion rate
_SENSOR_RATES = {"imu": 240.0, "gnss": 10.0, "baro": 40.0, "airspeed": 10.0, "mag": 40.0}


def _sensor_value(sensor: str, field: str, default: object) -> float:
    """A valid value different from the default for a sensor config field."""
    if field == "rate_hz":
        return _SENSOR_RATES[sensor]
    if field == "dropout":
        return 0.3
    if field == "inclination_rad":
        return 0.5
    if field.endswith("scale_factor_std"):
        return 0.05
    return 2.0 * float(default) if default else 0.5


def _sensor_effects() -> dict[str, Effect]:
    out: dict[str, Effect] = {"vehicle.sensors.preset": (_QUAD, _on_ekf, _set("vehicle.0.sensors.preset", "tactical"))}
    for f in schema_fields():
        if not f.startswith("vehicle.sensors.") or f == "vehicle.sensors.preset" or f in SHOWN_ELSEWHERE:
            continue
        parts = f.split(".")[2:]
        model: typing.Any = sc.SensorsSpec.model_fields[parts[0]].annotation.__args__[0]
        cfg = model()
        default = cfg
        for p in parts[1:]:
            default = getattr(default, p)
        base = _HAPS if parts[0] == "airspeed" else _QUAD
        value = _sensor_value(parts[0], parts[-1], default)
        out[f] = (base, _on_ekf, _set("vehicle.0.sensors." + ".".join(parts), value))
    return out


def _on_ekf(d: dict) -> None:
    _quad(d)["estimator"] = "ekf"


_RANGE_ERROR = ("noise_std", "bias_init_std", "bias_rw", "scale_factor_std", "quantum")
_FAULTS = ("GnssLoss", "SensorBias", "SensorStuck", "MotorFailure", "Gust")
LABELS = {
    "schema_version": "the file format's version (one value)",
    "name": "the run's name",
    "description": "free text",
    "object.id": "names the object",
    "obstacle.id": "names the obstacle",
    "geofence.id": "names the geofence",
    "vehicle.name": "names the vehicle",
    **{f"fault<{k}>.vehicle": "names the faulty vehicle" for k in _FAULTS},
    **{f"fault<{k}>.kind": "the union's tag" for k in _FAULTS},
}

SHOWN_ELSEWHERE = {
    "vehicle.sensors.imu.dropout": "only 0 is valid (the IMU drives the filter): tests/test_sensors_config.py",
    "vehicle.sensors.imu.latency_s": "only 0 is valid (the IMU is the time base): tests/test_sensors_config.py",
    "mavlink.enabled": "tests/test_mavlink_live.py (needs a ground-station socket)",
    "mavlink.gcs_host": "tests/test_mavlink_live.py",
    "mavlink.base_port": "tests/test_mavlink_live.py",
    "mavlink.rate_hz": "tests/test_mavlink_live.py",
    "mavlink.pace": "tests/test_mavlink_live.py",
}
EFFECTS |= _sensor_effects()


def _planner_fields() -> list[str]:
    return [f for f in schema_fields() if f.startswith("vehicle.planner<")]


# planner types and their options act only in encounters (traffic, obstacles, storms): each
# needs its own short encounter baseline
NOT_YET_SHOWN = {
    "metrics.well_clear_horizontal": "acts on the report's metrics, not on the log",
    "metrics.well_clear_vertical": "acts on the report's metrics, not on the log",
    "weather.nowcast_files": "nowcast GeoJSON files from disk (new on main): needs a nowcast-file fixture",
    **{
        f"mavlink.{k}": "new on main (MAVLink hardening): needs a ground-station socket, not checked here"
        for k in ("bind_host", "gcs_component_id", "gcs_system_id", "max_height", "max_range", "signing_key_file")
    },
    **dict.fromkeys(
        (
            "metrics.nmac_horizontal",
            "metrics.nmac_vertical",
            "vehicle.energy.altitude_schedule.ceiling",
            "vehicle.energy.altitude_schedule.floor",
            "vehicle.energy.altitude_schedule.soc_high",
            "vehicle.energy.altitude_schedule.soc_low",
            "vehicle.energy.enabled",
            "vehicle.energy.initial_soc",
            "vehicle.mission.repeat",
        ),
        "new on main while issue 15 was open (energy model, NMAC volume, mission repeat): to be shown",
    ),
    **{
        f"vehicle.lidar.{k}": "acts on the reach-set planner's occupancy grid; follow_mission logs only hit counts"
        for k in ("rate_hz", "frame", *(f"range_error.{e}" for e in _RANGE_ERROR))
    },
    **{
        f: "planner option: needs an encounter baseline per planner type"
        for f in _planner_fields()
        if f not in EFFECTS and not f.endswith(".type")
    },
}
LABELS |= {f: "the planner union's tag" for f in _planner_fields() if f.endswith(".type")}


def test_every_field_is_accounted_for():
    fields = set(schema_fields())
    lists = {"EFFECTS": EFFECTS, "LABELS": LABELS, "SHOWN_ELSEWHERE": SHOWN_ELSEWHERE, "NOT_YET_SHOWN": NOT_YET_SHOWN}
    placed = [f for d in lists.values() for f in d]
    twice = sorted({f for f in placed if placed.count(f) > 1})
    assert not twice, f"fields in more than one list: {twice}"
    assert not sorted(fields - set(placed)), "fields with no shown effect and no label"
    assert not sorted(set(placed) - fields), "listed fields that are not in the schema"


_BASELINES: dict[str, dict[str, tuple]] = {}


def _digests(data: dict, tmp: Path, tag: str) -> dict[str, tuple]:
    path = tmp / f"{tag}.mcap"
    run_scenario(sc.parse_scenario(data, tag), path, scenario_text=tomli_w.dumps(data))
    return {t: (n, h) for t, (n, h, wall) in _compare.channel_digests(path).items() if not wall}


@pytest.mark.closed_loop
@pytest.mark.parametrize("field", sorted(EFFECTS))
def test_field_changes_the_log(field, tmp_path):
    base, prepare, change = EFFECTS[field]
    before = copy.deepcopy(base)
    if prepare is not None:
        prepare(before)
    key = tomli_w.dumps(before)
    if key not in _BASELINES:
        _BASELINES[key] = _digests(before, tmp_path, "before")
    after = copy.deepcopy(before)
    if change is _gains:
        change(after, tmp_path)
    else:
        change(after)
    assert after != before, "the change changes nothing in the scenario"
    diff = _digests(after, tmp_path, "after")
    changed = sorted(t for t in diff.keys() | _BASELINES[key].keys() if diff.get(t) != _BASELINES[key].get(t))
    assert changed, f"{field}: the log is identical"
