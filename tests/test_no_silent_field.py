"""No silent field: every field of the scenario schema acts on the run, or is a label.

The walk covers the whole schema (nested sections, every member of a tagged union, the planner
types' options from the registry). Each field must be in exactly one of:

- ``EFFECTS``: a change of the field, applied to a short baseline run (1-11 s of sim time, ideal
  sensors unless the field is a sensor's), must change the MCAP log (some channel's messages);
- ``DECISIONS``: planner options. The type's planner, built from the scenario as the runner
  builds it, re-run on the recorded inputs of a short encounter of that type (traffic,
  obstacles, storms; flown once per module), must make another plan at some call (inputs equal
  up to that call: the closed loop logs the difference there); the few ``RECORDS_ONLY``
  options must make another planner record (candidate costs, rule decisions);
- ``REPORT``: metrics thresholds, which must change the run's metrics report in the log;
- ``LABELS``: names and tags that only identify things;
- ``SHOWN_ELSEWHERE``: fields that need a ground-station socket or have one valid value, with
  the tests that show them (checked to exist).

A new schema field fails ``test_every_field_is_accounted_for`` until it is placed.
"""

from __future__ import annotations

import copy
import importlib.util
import json
import re
import typing
from collections.abc import Callable, Mapping
from pathlib import Path

import pytest
import tomli_w
from pydantic import BaseModel

from aircraft.registry import get_airframe
from sim import scenario as sc
from sim.core.plan import Plan, Planner, Threats
from sim.core.state import VehicleState
from sim.mcap_read import read_info
from sim.planner_records import WALLCLOCK_FIELDS, RecordSink
from sim.planner_registry import PLANNERS
from sim.replay.rerun import RerunReport, rerun_planner
from sim.runner import run_scenario
from sim.vehicle_setup import scenario_planner

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("compare_log_payloads", ROOT / "scripts" / "compare_log_payloads.py")
assert _spec is not None and _spec.loader is not None
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

_QUAD: dict[str, typing.Any] = {
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


# one scripted cell next to the generated ones, for the storm.* fields
_SCRIPTED_STORM = _set("weather", _WEATHER | {"storm": [{"points": [[0, 0], [0, 900], [900, 0]]}]})


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


def _haps_near_start_mission(d: dict) -> None:
    """The HAPS starts within its acceptance radius of its only waypoint: the mission completes
    at once."""
    _quad(d)["mission"].update(waypoints=[{"north": 60.0, "east": 0.0, "altitude": 18000.0}], acceptance_radius=100.0)


def _weather_for(duration: float) -> Callable[[dict], None]:
    """The weather section and a run long enough for a second nowcast."""

    def prepare(d: dict) -> None:
        d.update(weather=copy.deepcopy(_WEATHER), duration=duration)

    return prepare


def _gains(d: dict, tmp: Path) -> None:
    text = (ROOT / "aircraft" / "quadrotor" / "gains.toml").read_text().replace("kp_xy = 0.95", "kp_xy = 0.5")
    (tmp / "gains.toml").write_text(text)
    _quad(d)["gains"] = str(tmp / "gains.toml")


def _scheduled(soc: float) -> Callable[[dict], None]:
    """Energy management by altitude (17-19 km) from state of charge ``soc`` at night (the
    battery drains: a HAPS at the ceiling's threshold 0.95 falls below 0.94995 within 2 s)."""

    def prepare(d: dict) -> None:
        d["start_time"] = "2026-06-21T00:00:00Z"
        _quad(d)["energy"] = {"initial_soc": soc, "altitude_schedule": {"floor": 17000.0, "ceiling": 19000.0}}

    return prepare


_NOWCASTS = str(ROOT / "scenarios" / "mptp" / "nowcasts") + "/"
# a quadrotor as high as its ceiling (7,800 m, aircraft/registry.py) lets it fly
_QUAD_MISSION_HIGH = {"cruise_speed": 4.0, "waypoints": [{"north": 5.0, "east": 0.0, "altitude": 7000.0}]}

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
    "weather.nowcast_files": (
        _QUAD,
        _set("weather", {"nowcast_files": [_NOWCASTS + "nowcast_00000s.geojson"]}),
        _set("weather.nowcast_files", [_NOWCASTS + "nowcast_00300s.geojson"]),  # issued at 300 s
    ),
    "weather.base": (_QUAD, _set("weather", _WEATHER), _set("weather.base", 500.0)),
    "weather.top": (_QUAD, _set("weather", _WEATHER), _set("weather.top", 9000.0)),
    "weather.storm.base": (
        _QUAD,
        _SCRIPTED_STORM,
        _set("weather.storm.0.base", 500.0),
    ),
    "weather.storm.top": (
        _QUAD,
        _SCRIPTED_STORM,
        _set("weather.storm.0.top", 9000.0),
    ),
    "weather.storm.points": (
        _QUAD,
        _SCRIPTED_STORM,
        _set("weather.storm.0.points", [[0, 0], [0, 800], [800, 0]]),
    ),
    "weather.storm.drift_north": (
        _QUAD,
        _SCRIPTED_STORM,
        _set("weather.storm.0.drift_north", 3.0),
    ),
    "weather.storm.drift_east": (
        _QUAD,
        _SCRIPTED_STORM,
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
        lambda d: _quad(d).update(aircraft="quadrotor", initial={"altitude": 7000.0}, mission=_QUAD_MISSION_HIGH),
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
    "vehicle.mission.repeat": (_HAPS, _haps_near_start_mission, _set("vehicle.0.mission.repeat", True)),
    "vehicle.mission.guidance": (_QUAD, None, _set("vehicle.0.mission.guidance", "step")),
    "vehicle.energy.enabled": (_HAPS, None, _set("vehicle.0.energy.enabled", False)),
    "vehicle.energy.initial_soc": (_HAPS, None, _set("vehicle.0.energy.initial_soc", 0.5)),
    "vehicle.energy.altitude_schedule.floor": (
        _HAPS,
        _scheduled(0.93),
        _set("vehicle.0.energy.altitude_schedule.floor", 16000.0),
    ),
    "vehicle.energy.altitude_schedule.ceiling": (
        _HAPS,
        _scheduled(1.0),
        _set("vehicle.0.energy.altitude_schedule.ceiling", 20000.0),
    ),
    "vehicle.energy.altitude_schedule.soc_high": (
        _HAPS,
        _scheduled(0.93),
        _set("vehicle.0.energy.altitude_schedule.soc_high", 0.92),
    ),
    "vehicle.energy.altitude_schedule.soc_low": (
        _HAPS,
        _scheduled(0.95),
        _set("vehicle.0.energy.altitude_schedule.soc_low", 0.94995),
    ),
    "vehicle.planner<FollowMissionPlanner>.rate_hz": (_QUAD, None, _set("vehicle.0.planner.rate_hz", 2.0)),
}

_UTM_LINK = {"latency": 0.1, "loss": 0.0, "outage": [{"start": 1.0, "end": 2.0}]}
_SPOOF = {"vehicle": "quad", "peer": "ghost", "at": 1.0, "north": 5.0, "east": 0.0, "altitude": 420.0}


def _utm(d: dict) -> None:
    """The UTM authority over the quadrotor (which only notifies it), an outage of its link
    and a forged case on its downlink."""
    d["utm"] = {"spoof": [dict(_SPOOF)]}
    _quad(d)["utm_link"] = copy.deepcopy(_UTM_LINK)


_MANDATE = {"id": "m1", "vehicle": "quad", "at": 1.0, "north": 50.0, "east": 0.0, "radius": 10.0}


def _utm_peers(d: dict) -> None:
    """:func:`_utm` with a second quadrotor 30 m east and a vehicle-to-vehicle link on both
    (their notifications to each other are logged with their arrival), and a mandate to the
    first (logged in its directives)."""
    _utm(d)
    other = copy.deepcopy(_quad(d))
    other["name"] = "quad2"
    other["initial"]["east"] = 30.0
    other.pop("utm_link")
    d["vehicle"].append(other)
    for v in d["vehicle"]:
        v["peer_link"] = copy.deepcopy(_UTM_LINK)
    d["utm"]["mandate"] = [dict(_MANDATE)]


def _utm_weather(d: dict) -> None:
    """:func:`_utm` with a weather service (the quadrotor gets its nowcasts unless the
    authority takes the feed)."""
    _utm(d)
    _set("weather", dict(_WEATHER))(d)


def _utm_cluster(d: dict) -> None:
    """:func:`_utm` with the authority of one airspace cluster whose box holds the quadrotor."""
    _utm(d)
    d["utm"]["cluster"] = [{"id": "a", "east_min": -10.0, "east_max": 10.0, "north_min": -10.0, "north_max": 10.0}]


def _utm_cluster_beside(d: dict) -> None:
    """:func:`_utm_cluster` with the box 20-40 m east: the quadrotor notifies it from the hand-over
    band (directed by nobody)."""
    _utm_cluster(d)
    d["utm"]["cluster"][0] |= {"east_min": 20.0, "east_max": 40.0}


EFFECTS |= {
    "utm.cluster.id": (_QUAD, _utm_cluster, _set("utm.cluster.0.id", "b")),
    "utm.cluster.east_min": (_QUAD, _utm_cluster, _set("utm.cluster.0.east_min", 1.0)),
    "utm.cluster.east_max": (_QUAD, _utm_cluster, _set("utm.cluster.0.east_max", -1.0)),
    "utm.cluster.north_min": (_QUAD, _utm_cluster, _set("utm.cluster.0.north_min", 1.0)),
    "utm.cluster.north_max": (_QUAD, _utm_cluster, _set("utm.cluster.0.north_max", -1.0)),
    "utm.handover": (_QUAD, _utm_cluster_beside, _set("utm.handover", 0.0)),
    "utm.frame": (_QUAD, _utm, _set("utm.frame", 0.5)),
    "utm.weather": (_QUAD, _utm_weather, _set("utm.weather", True)),
    "utm.lost_after": (_QUAD, _utm, _set("utm.lost_after", 1.0)),  # the outage then loses the link
    "utm.spoof.peer": (_QUAD, _utm, _set("utm.spoof.0.peer", "phantom")),
    "utm.spoof.at": (_QUAD, _utm, _set("utm.spoof.0.at", 2.0)),
    "utm.spoof.duration": (_QUAD, _utm, _set("utm.spoof.0.duration", 1.0)),
    "utm.spoof.north": (_QUAD, _utm, _set("utm.spoof.0.north", 6.0)),
    "utm.spoof.east": (_QUAD, _utm, _set("utm.spoof.0.east", 1.0)),
    "utm.spoof.altitude": (_QUAD, _utm, _set("utm.spoof.0.altitude", 421.0)),
    "utm.spoof.margin": (_QUAD, _utm, _set("utm.spoof.0.margin", 20.0)),
    "vehicle.utm_link.latency": (_QUAD, _utm, _set("vehicle.0.utm_link.latency", 0.3)),
    "vehicle.utm_link.loss": (_QUAD, _utm, _set("vehicle.0.utm_link.loss", 0.5)),
    "vehicle.utm_link.outage.start": (_QUAD, _utm, _set("vehicle.0.utm_link.outage.0.start", 0.0)),
    "vehicle.utm_link.outage.end": (_QUAD, _utm, _set("vehicle.0.utm_link.outage.0.end", 2.5)),
    "vehicle.peer_link.latency": (_QUAD, _utm_peers, _set("vehicle.0.peer_link.latency", 0.3)),
    "vehicle.peer_link.loss": (_QUAD, _utm_peers, _set("vehicle.0.peer_link.loss", 0.5)),
    "vehicle.peer_link.outage.start": (_QUAD, _utm_peers, _set("vehicle.0.peer_link.outage.0.start", 0.0)),
    "vehicle.peer_link.outage.end": (_QUAD, _utm_peers, _set("vehicle.0.peer_link.outage.0.end", 2.5)),
    "utm.mandate.at": (_QUAD, _utm_peers, _set("utm.mandate.0.at", 2.0)),
    "utm.mandate.duration": (_QUAD, _utm_peers, _set("utm.mandate.0.duration", 1.0)),
    "utm.mandate.north": (_QUAD, _utm_peers, _set("utm.mandate.0.north", 60.0)),
    "utm.mandate.east": (_QUAD, _utm_peers, _set("utm.mandate.0.east", 5.0)),
    "utm.mandate.radius": (_QUAD, _utm_peers, _set("utm.mandate.0.radius", 12.0)),
    "utm.mandate.altitude_min": (_QUAD, _utm_peers, _set("utm.mandate.0.altitude_min", 300.0)),
    "utm.mandate.altitude_max": (_QUAD, _utm_peers, _set("utm.mandate.0.altitude_max", 500.0)),
}

_LIDAR: dict[str, object] = {
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
    "rate_hz": 10.0,
    "frame": "body",
    "range_error.noise_std": 0.5,
    "range_error.bias_init_std": 0.5,
    "range_error.bias_rw": 0.5,
    "range_error.scale_factor_std": 0.05,
    "range_error.quantum": 0.5,
    "range_resolution_m": 0.5,
}
for _k, _v in _LIDAR.items():
    EFFECTS[f"vehicle.lidar.{_k}"] = (_QUAD, None, _set(f"vehicle.0.lidar.{_k}", _v))

# sensor fields act on the EKF baseline (the HAPS for the pitot: a multirotor has none); the
# rates must divide the plant rate (quadrotor 240 Hz, HAPS 120 Hz) and be multiples of the fusion rate
_SENSOR_RATES = {"imu": 120.0, "gnss": 10.0, "baro": 40.0, "airspeed": 10.0, "mag": 40.0}  # IMU default: 240


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
    return 2.0 * float(typing.cast(float, default)) if default else 0.5


def _sensor_effects() -> dict[str, Effect]:
    out: dict[str, Effect] = {"vehicle.sensors.preset": (_QUAD, _on_ekf, _set("vehicle.0.sensors.preset", "tactical"))}
    for f in schema_fields():
        if not f.startswith("vehicle.sensors.") or f == "vehicle.sensors.preset" or f in SHOWN_ELSEWHERE:
            continue
        parts = f.split(".")[2:]
        model: typing.Any = typing.get_args(sc.SensorsSpec.model_fields[parts[0]].annotation)[0]
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
    "utm.spoof.vehicle": "names the vehicle whose downlink carries the forged case",
    "utm.mandate.id": "names the mandate in the directives and acknowledgements",
    "utm.mandate.vehicle": "names the vehicle the mandate binds",
    **{f"fault<{k}>.vehicle": "names the faulty vehicle" for k in _FAULTS},
    **{f"fault<{k}>.kind": "the union's tag" for k in _FAULTS},
}

_WIRED = "tests/test_mavlink_authority.py::test_scenario_mavlink_settings_reach_every_link (scenario to every link)"
SHOWN_ELSEWHERE = {
    "vehicle.planner<MptpPlanner>.options.hold_speed_correction": (
        "acts when the goal is covered over the whole horizon (a holding orbit): "
        "tests/test_mptp_holding_speed.py::test_the_planner_holds_on_the_corrected_circle_when_the_goal_is_covered; "
        "flown at the commanded V_cor in closed loop: "
        "tests/test_mptp_holding_speed.py::test_the_hold_is_flown_at_v_cor_and_reaches_its_states_on_time"
    ),
    "vehicle.planner<MptpPlanner>.options.holding_points": (
        "acts when the goal is covered over the whole horizon (a holding orbit): "
        "tests/test_mptp_holding_speed.py::test_a_predefined_holding_location_is_used_when_it_is_free; "
        "the nearest free one is held at: "
        "tests/test_mptp_holding_speed.py::test_a_hold_plan_commands_v_to_the_holding_point_and_v_cor_on_its_orbit"
    ),
    "vehicle.planner<MptpPlanner>.options.wait_step_min_s": (
        "acts on the wait bound's time step and cells (at most 3 steps per dt no shorter than it): "
        "tests/test_mptp_optimality.py::test_the_wait_step_sets_the_wait_bound_and_changes_the_search"
    ),
    "vehicle.planner<ReachsetPlanner>.options.stop_and_wait": (
        "multirotors only (refused otherwise), acts in emergency mode when stopping pays: "
        "tests/test_reachset_stop_and_wait.py::test_herded_multirotor_stops_and_crosses_behind_the_intruder; "
        "tests/test_reachset_stop_and_wait.py::test_stop_and_wait_is_an_option_of_vehicles_that_turn_in_place"
    ),
    "vehicle.planner<MptpPlanner>.options.nav_std_max_m": (
        "acts on the first plan only, while the estimate's horizontal sigma is above it (a DEGRADED wait): "
        "tests/test_mptp_nav_wait.py::test_nav_std_max_m_sets_the_threshold_and_an_estimate_without_sigma_never_waits; "
        "in closed loop on the EKF: "
        "tests/test_mptp_nav_wait.py::test_the_storm_crossing_on_its_ekf_plans_after_the_first_gnss_fix"
    ),
    "vehicle.planner<MptpPlanner>.options.keep_within_m": (
        "acts at a replan while the plan being flown reaches the goal (kept or not by the aircraft's "
        "distance from it): tests/test_mptp_plan_keeping.py::test_an_aircraft_off_the_plan_gets_a_new_one"
    ),
    "vehicle.planner<MptpPlanner>.options.keep_slack": (
        "acts at a replan while the plan being flown reaches the goal (replaced by a much earlier one): "
        "tests/test_mptp_plan_keeping.py::test_a_new_plan_much_earlier_than_the_kept_one_replaces_it"
    ),
    "vehicle.planner<MptpPlanner>.options.dominance_s": (
        "acts once the capped search meets a place again at another time (waiting): "
        "tests/test_mptp_optimality.py::test_the_dominance_window_changes_the_search"
    ),
    "vehicle.sensors.imu.dropout": "only 0 is valid (the IMU drives the filter): tests/test_sensors_config.py",
    "vehicle.sensors.imu.latency_s": "only 0 is valid (the IMU is the time base): tests/test_sensors_config.py",
    # MAVLink needs a ground-station socket: the scenario's settings reach every link, and each
    # link setting acts in its own test
    "mavlink.enabled": "tests/test_mavlink_live.py::test_gcs_uploads_a_mission_that_the_vehicle_flies",
    "mavlink.base_port": f"{_WIRED}; tests/test_mavlink_live.py::test_gcs_uploads_a_mission_that_the_vehicle_flies",
    "mavlink.gcs_host": f"{_WIRED}; tests/test_mavlink_authority.py::"
    "test_non_loopback_gcs_needs_an_explicit_bind_and_loopback_is_the_default",
    "mavlink.bind_host": f"{_WIRED}; tests/test_mavlink_authority.py::"
    "test_non_loopback_gcs_needs_an_explicit_bind_and_loopback_is_the_default",
    "mavlink.rate_hz": f"{_WIRED}; tests/test_mavlink_bridge.py::test_rates_are_limited_by_sim_time",
    "mavlink.pace": f"{_WIRED}; tests/test_mavlink_replay.py::test_pacer_holds_sim_time_to_n_times_wall_time",
    "mavlink.gcs_system_id": f"{_WIRED}; tests/test_mavlink_live.py::"
    "test_upload_from_another_system_id_is_refused_and_the_flight_unchanged",
    "mavlink.gcs_component_id": f"{_WIRED}; tests/test_mavlink_authority.py::test_configured_component_is_required",
    "mavlink.signing_key_file": "tests/test_mavlink_live.py::"
    "test_with_signing_the_signed_gcs_is_obeyed_and_unsigned_commands_refused",
    "mavlink.max_height": f"{_WIRED}; tests/test_mavlink_authority.py::"
    "test_position_targets_outside_the_envelope_are_dropped",
    "mavlink.max_range": f"{_WIRED}; tests/test_mavlink_authority.py::"
    "test_mission_items_outside_the_envelope_are_refused",
}
EFFECTS |= _sensor_effects()


# --- planner options: decisions on the recorded inputs of a short encounter per planner type ---
#
# A planner option acts where the planner decides: each type has a short encounter baseline
# (traffic, obstacles, storms), flown once per module. The planner is then built from the
# scenario twice, through the runner's own construction (``scenario_planner``), before and after
# the option's change, and re-run on the baseline's recorded inputs (``rerun_planner``); its
# plans and its own log records (wall-clock fields left out) must differ at some call. Inputs
# equal up to that call, the closed loop logs a different plan or record there.


def _uas(name: str, north: float, east: float, heading: float, goal: tuple[float, float], options: dict) -> dict:
    return {
        "name": name,
        "aircraft": "quadrotor",
        "estimator": "perfect",
        "initial": {"north": north, "east": east, "altitude": 420.0, "heading": heading},
        "mission": {
            "cruise_speed": 5.0,
            "acceptance_radius": 1.0,
            "waypoints": [{"north": goal[0], "east": goal[1], "altitude": 420.0}],
        },
        "planner": {"type": "reachset", "rate_hz": 1.0, "options": options},
    }


_ORIGIN = {"lat": 47.0, "lon": 8.0, "altitude": 400.0}
_TRACKER = {
    "rate_hz": 10,
    "latency": 0.1,
    "position_noise_horizontal": 0.3,
    "position_noise_vertical": 0.3,
    "velocity_noise": 0.2,
}
_RULES = ["detect", "resolve", "close", "head_on", "converging", "overtake", "right_plane_heading", "safety_margin"]


def _sphere(name: str, radius: float, north: float, east: float, alt: float, **more: object) -> dict:
    return {"id": name, "radius": radius, "north": north, "east": east, "altitude": alt, **more}


ENCOUNTERS: dict[str, dict] = {
    # a quadrotor meets a climbing main threat, two diagonal ones, two spheres that appear on
    # either side of its avoidance path at 0.6 s and one far down the reference
    "geometric": {
        "name": "silent_geometric",
        "seed": 3,
        "duration": 1.0,
        "origin": _ORIGIN,
        "surveillance": _TRACKER,
        "object": [
            _sphere("main", 2.0, 14.0, 0.0, 418.0, velocity={"down": -1.0}),
            _sphere("diag_a", 1.0, 8.0, 8.0, 424.0, velocity={"north": 1.5, "east": -1.5}),
            _sphere("diag_b", 1.0, 22.0, -8.0, 424.0, velocity={"north": -1.5, "east": 1.5}),
            _sphere("late_west", 1.5, 11.5, -6.0, 420.0, appear=0.6),
            _sphere("late_east", 1.5, 11.5, 6.0, 420.0, appear=0.6),
            _sphere("far", 1.0, 55.0, 0.0, 420.0),
        ],
        "vehicle": [
            {
                "name": "quad",
                "aircraft": "quadrotor",
                "estimator": "perfect",
                "initial": {"altitude": 420.0},
                "mission": {
                    "cruise_speed": 5.0,
                    "acceptance_radius": 2.0,
                    "waypoints": [{"north": 60.0, "east": 0.0, "altitude": 420.0}],
                },
                "planner": {"type": "geometric", "rate_hz": 10.0},
            }
        ],
    },
    # three reach-set quadrotors (head-on and converging) by a building, under a keep-in
    # ceiling and beside a keep-out zone
    "reachset": {
        "name": "silent_reachset",
        "seed": 3,
        "duration": 3.0,
        "origin": _ORIGIN,
        "surveillance": _TRACKER | {"rate_hz": 2},
        "obstacle": [
            {"id": "mast", "shape": "box", "north": 6.0, "east": 10.0, "length": 2.0, "width": 2.0, "top": 440.0}
        ],
        "geofence": [
            {"id": "zone", "points": [[-60, -60], [-60, 100], [60, 100], [60, -60]], "floor": 300.0, "ceiling": 430.0},
            {
                "id": "nofly",
                "keep_in": False,
                "points": [[-3, 12], [-3, 22], [-12, 12]],
                "floor": 300.0,
                "ceiling": 500.0,
            },
        ],
        "vehicle": [
            _uas("uas1", 0.0, 0.0, 90.0, (0.0, 80.0), {}),
            _uas("uas2", 0.0, 40.0, 270.0, (0.0, -40.0), {}),
            _uas("uas3", -25.0, 25.0, 0.0, (40.0, 25.0), {}),
        ],
    },
    # the same three under the rules of the air in open air: a head-on and a converging case open
    "rules": {
        "name": "silent_rules",
        "seed": 3,
        "duration": 5.0,
        "origin": _ORIGIN,
        "surveillance": _TRACKER | {"rate_hz": 2},
        "vehicle": [
            _uas("uas1", 0.0, 0.0, 90.0, (0.0, 80.0), {"rules": _RULES}),
            _uas("uas2", 0.0, 60.0, 270.0, (0.0, -40.0), {"rules": _RULES}),
            _uas("uas3", -30.0, 30.0, 0.0, (40.0, 30.0), {"rules": _RULES}),
        ],
    },
    # two of them under the rules of the air: one converging case, resolved, then closed at 10 s
    "rules_pair": {
        "name": "silent_rules_pair",
        "seed": 3,
        "duration": 11.0,
        "origin": _ORIGIN,
        "surveillance": _TRACKER | {"rate_hz": 2},
        "vehicle": [
            _uas("uas1", 0.0, 0.0, 90.0, (0.0, 80.0), {"rules": _RULES}),
            _uas("uas3", -30.0, 30.0, 0.0, (40.0, 30.0), {"rules": _RULES}),
        ],
    },
    # one of them under the rules with weather cases, a storm cell across its route 60-100 m ahead
    "rules_weather": {
        "name": "silent_rules_weather",
        "seed": 3,
        "duration": 4.0,
        "origin": _ORIGIN,
        "weather": {"cells": 0, "nowcast_period": 10.0, "horizon": 60.0, "step": 10.0}
        | {"storm": [{"points": [[-20.0, 60.0], [20.0, 60.0], [20.0, 100.0], [-20.0, 100.0]]}]},
        "vehicle": [
            _uas("uas1", 0.0, 0.0, 90.0, (0.0, 200.0), {"rules": [*_RULES, "weather"], "rules_unit": 5.0}),
        ],
    },
    # a quadrotor pursues one of two others
    "pursuit": {
        "name": "silent_pursuit",
        "seed": 3,
        "duration": 1.0,
        "origin": _ORIGIN,
        "surveillance": _TRACKER,
        "vehicle": [
            _uas("uas1", 0.0, 0.0, 90.0, (0.0, 80.0), {}) | {"planner": {"type": "follow_mission"}},
            _uas("uas2", 30.0, 0.0, 90.0, (30.0, 80.0), {}) | {"planner": {"type": "follow_mission"}},
            _uas("chaser", 15.0, -20.0, 90.0, (15.0, 80.0), {})
            | {"planner": {"type": "pursuit", "rate_hz": 2.0, "options": {"target": "uas1"}}},
        ],
    },
    # the HAPS at 18 km before a line of three storm cells (shipped mptp/storm_crossing.toml),
    # heading north, a right angle off its goal (its first legs turn); 40 search expansions
    # keep each replan cheap
    "mptp": {
        "name": "silent_mptp",
        "seed": 5,
        "duration": 2.0,
        "start_time": "2026-06-21T14:00:00Z",
        "origin": {"lat": 47.0, "lon": 8.0, "altitude": 0.0},
        "weather": {
            "cells": 3,
            "size": 60000.0,
            "drift_east": 2.0,
            "drift_spread": 0.5,
            "radius": 3000.0,
            "split_probability": 0.0,
            "life": 18000.0,
            "centres": [[0, 22000], [9000, 30000], [-9000, 32000]],
            "nowcast_period": 300.0,
        },
        "vehicle": [
            {
                "name": "haps",
                "aircraft": "haps",
                "estimator": "perfect",
                "initial": {"altitude": 18000.0, "airspeed": 26.0, "heading": 0.0},
                "mission": {
                    "cruise_speed": 26.0,
                    "acceptance_radius": 10.0,  # below the fly-over turns' vertex spacing (turn_model)
                    "waypoints": [{"north": 0.0, "east": 50000.0, "altitude": 18000.0}],
                },
                "planner": {"type": "mptp", "rate_hz": 1.0, "options": {"max_expansions": 40}},
            }
        ],
    },
}

# the same with the HAPS at 17 km climbing to 18 km and the cells from 18.5 km up (the MPTP's
# vertical options: within 1 km of the heights it reaches in the horizon at 1 m/s)
# the geometric encounter on the default EKF, whose estimates carry a position uncertainty, with
# the allowance for it on: its plans re-run from the log only if the log keeps that uncertainty
ENCOUNTERS["geometric_ekf"] = copy.deepcopy(ENCOUNTERS["geometric"]) | {"name": "silent_geometric_ekf"}
del ENCOUNTERS["geometric_ekf"]["vehicle"][0]["estimator"]
ENCOUNTERS["geometric_ekf"]["vehicle"][0]["planner"]["options"] = {"k_sigma_own": 1.0}
ENCOUNTERS["mptp_high_cells"] = copy.deepcopy(ENCOUNTERS["mptp"]) | {"name": "silent_mptp_high_cells"}
ENCOUNTERS["mptp_high_cells"]["weather"]["base"] = 18_500.0
ENCOUNTERS["mptp_high_cells"]["vehicle"][0]["initial"]["altitude"] = 17_000.0


def _options(**values: object) -> Callable[[dict], None]:
    """A change setting planner options of every vehicle whose planner takes options (all but
    follow_mission)."""

    def change(d: dict) -> None:
        for v in d["vehicle"]:
            if v["planner"]["type"] != "follow_mission":
                v["planner"].setdefault("options", {}).update(values)

    return change


_GEOMETRIC = {
    "caps": {"time_lo": 1.0, "time_hi": 5.0, "energy_lo": 100.0, "energy_hi": 900.0},
    "cmo_max_objects": 1,
    "cmo_max_range_m": 5.0,
    "cmo_min_distance": 5.0,
    "cmo_threat_samples": 3,
    "collision_radius": 6.0,
    "conflict_horizon_s": 0.5,
    "dynamic_mode": "swept",
    "g": 5.0,
    "hover_literal_ki": True,
    "k1": 5.0,
    "k2": 5.0,
    "k_p": 100.0,
    "k_sigma": 2.0,
    "l": 6,
    "log_limits": [[-3.0, 2.5], [-0.1, 0.1], [-3.0, 0.001]],
    "main_threat_extension_s": 3.0,
    "max_cost": 0.01,
    "min_height_m": 21.0,
    "min_replan_interval_s": 5.0,
    "min_sep_factor": 4.0,
    "n_planes": 1,
    "omega_factor": 5.0,
    "path_types": ["simple"],
    "rejoin_check_s": 8.0,
    "replan_max_offset_m": 0.0,
    "rho": 0.3,
    "select_margin_m": 3.0,
    "smoothness": "second_derivative",
    "start_shift_s": 0.0,
    "uav_shape": "sphere_circumscribed",
    "weights": [0.8, 0.1, 0.1],
    "x_step_fraction": 0.3,
}
_REACHSET = {
    "period": 0.5,
    "constraint_margin": 3.0,
    "constraint_mode": "circle",
    "intruder_margin": 4.0,
    "intruder_margin_vertical": 3.0,
    "separations": ["horizontal"],
}
_RULES_OPTIONS = {
    "rules": [r for r in _RULES if r != "head_on"],
    "rules_unit": 2.0,
    "rules_universal": 8.0,
    "rules_head_on": 9.0,
    "rules_overtake": 9.0,
    "rules_plane_tolerance": 3.0,
    "rules_widest": False,
    "rules_bloat": 3.0,
    "rules_time_margin": 0.5,
    "rules_established_speed": 0.2,
    "rules_settle": 5.0,
    "rules_deadlock_frames": 1,
    "rules_filed": {"uas2": {"category": "balloon"}, "uas3": {"category": "balloon"}},
}
_MPTP = {
    "bank_max": 0.2,
    "cluster_eps_m": 9000.0,
    "course_change_max": 0.5,
    "dt_s": 45.0,
    "g": 5.0,
    "goal_track": [[0.0, 0.0, 50000.0], [3600.0, 10000.0, 50000.0]],
    "heuristic": "dijkstra",
    "horizon_s": 600.0,
    "line_aspect": 1.1,
    "max_expansions": 5,
    "mission_area": [[-20000, -5000], [-20000, 60000], [5000, 60000], [5000, -5000]],
    "prob_margin_max_m": 1000.0,
    "probability": 0.5,
    "probabilities": [0.999, 0.5],
    "downwind_factor": 3.0,
    "safety_area_steps": [[1.0, 5000.0]],
    "replan_period_s": 1.0,
    "ring_segments": 8,
    "safety_single_m": [1000.0, 1000.0, 1000.0],
    "search_weight": 1.0,
    "sigma_back_mps": 3.0,
    "sigma_front_mps": 3.0,
    "simplify_tol_m": 2000.0,
    "turn_model": "simulated",
    "turning": "left",
    "wind_error_ne_mps": [5.0, 5.0],
}

# (encounter, preparation applied before and after or None, the change)
Decision = tuple[str, Callable[[dict], None] | None, Callable[[dict], None]]
_PLANNER_MODEL = {
    "geometric": "GeometricPlanner",
    "reachset": "ReachsetPlanner",
    "rules": "ReachsetPlanner",
    "rules_pair": "ReachsetPlanner",
    "rules_weather": "ReachsetPlanner",
    "pursuit": "PursuitPlanner",
    "mptp": "MptpPlanner",
}


def _decision_table() -> dict[str, Decision]:
    out: dict[str, Decision] = {}
    for kind, values in (
        ("geometric", _GEOMETRIC),
        ("reachset", _REACHSET),
        ("rules", _RULES_OPTIONS),
        ("mptp", _MPTP),
    ):
        for k, v in values.items():
            out[f"vehicle.planner<{_PLANNER_MODEL[kind]}>.options.{k}"] = (kind, None, _options(**{k: v}))
    prefix = "vehicle.planner<GeometricPlanner>.options."
    out[prefix + "uav_shape"] = (
        "geometric",
        _options(collision_radius=4.0),
        _options(uav_shape="sphere_circumscribed"),
    )
    out[prefix + "main_threat_extension_s"] = (
        "geometric",
        _options(dynamic_mode="swept"),
        _options(main_threat_extension_s=3.0),
    )
    out[prefix + "k_sigma_own"] = ("geometric_ekf", None, _options(k_sigma_own=0.0))
    prefix = "vehicle.planner<MptpPlanner>.options."
    out[prefix + "safety_line_m"] = ("mptp", _options(line_aspect=1.0), _options(safety_line_m=[1000.0] * 3))
    out[prefix + "wind_forecast"] = ("mptp", _set("wind.east", 10.0), _options(wind_forecast="none"))
    out[prefix + "tas_mps"] = ("mptp", _options(speed_source="config"), _options(tas_mps=20.0))
    out[prefix + "speed_source"] = ("mptp", _options(tas_mps=20.0), _options(speed_source="config"))
    # the cells' base 500 m over the 18 km the HAPS reaches: inside the 1 km margin, outside 200 m
    out[prefix + "vertical_margin_m"] = ("mptp_high_cells", None, _options(vertical_margin_m=200.0))
    # at 0.1 m/s the HAPS reaches only 17.36 km in the horizon: 1.14 km under the cells' base
    out[prefix + "climb_rate_mps"] = ("mptp_high_cells", None, _options(climb_rate_mps=0.1))
    out[prefix + "roll_rate_max"] = ("mptp", _options(turn_model="simulated"), _options(roll_rate_max=0.5))
    out[prefix + "turn_bank_fraction"] = ("mptp", _options(turn_model="simulated"), _options(turn_bank_fraction=0.5))
    out[prefix + "start_lead_s"] = ("mptp", _options(turn_model="simulated"), _options(start_lead_s=5.0))
    prefix = "vehicle.planner<ReachsetPlanner>.options.rules_"
    filed = _options(rules_filed={"uas3": {"category": "uas_autonomous", "maneuverability": "vtol"}})
    out[prefix + "converging"] = ("rules_pair", None, _options(rules_converging=20.0))
    out[prefix + "navigation"] = ("rules_pair", None, _options(rules_navigation=["vertical"]))
    out[prefix + "navigation_spread"] = ("rules_pair", None, _options(rules_navigation_spread=50))
    out[prefix + "converging_extra"] = ("rules_pair", None, _options(rules_converging_extra=4.0))
    out[prefix + "category"] = ("rules_pair", filed, _options(rules_category="manned"))
    out[prefix + "maneuverability"] = ("rules_pair", filed, _options(rules_maneuverability="linear_propulsion"))
    # without the hold: where uas1 hovers out its soft deadlock the margin's shape does not act
    out[prefix + "barrel_half_height"] = (
        "rules_pair",
        _options(rules_airspace="controlled", rules_hold=False),
        _options(rules_barrel_half_height=0.5),
    )
    out[prefix + "airspace"] = (
        "rules_pair",
        _options(rules_barrel_half_height=0.5, rules_hold=False),
        _options(rules_airspace="controlled"),
    )
    out[prefix + "hold"] = ("rules_pair", None, _options(rules_hold=False))
    out[prefix + "close_after"] = ("rules_pair", None, _options(rules_close_after=5))
    out[prefix + "plane_horizon"] = ("rules_pair", None, _options(rules_plane_horizon=10.0))
    out[prefix + "plans"] = ("rules_pair", None, _options(rules_plans={"uas3": [[-20.0, 30.0], [-20.0, -100.0]]}))
    out[prefix + "weather_margin"] = ("rules_weather", None, _options(rules_weather_margin=10.0))
    out["vehicle.planner<PursuitPlanner>.options.target"] = ("pursuit", None, _options(target="uas2"))
    return out


DECISIONS = _decision_table()

# options that change the planner's logged decision records but not the plan flown in their
# encounter: the geometric avoider's energy and hover-power terms (g, rho, hover_literal_ki) are
# diagnostics outside the cost (spec avoidance-geometric.md §5); the others change candidate
# clearances and costs, or the rules' disabled nodes, case margins and chains, without moving
# the chosen path in a few seconds of flight
RECORDS_ONLY = {
    *(
        f"vehicle.planner<GeometricPlanner>.options.{k}"
        for k in ("cmo_threat_samples", "dynamic_mode", "g", "hover_literal_ki", "main_threat_extension_s", "rho")
    ),
    *(
        f"vehicle.planner<ReachsetPlanner>.options.rules_{k}"
        for k in (
            "airspace",
            "barrel_half_height",
            "bloat",
            "close_after",
            "converging_extra",
            "filed",
            "overtake",
            "plane_horizon",
            "plane_tolerance",
            "widest",
        )
    ),
}

# the planner's call rate acts in the closed loop: the calls are at other times
for _kind, _model in _PLANNER_MODEL.items():
    if not _kind.startswith("rules"):
        _chaser = 2 if _kind == "pursuit" else 0
        EFFECTS[f"vehicle.planner<{_model}>.rate_hz"] = (
            ENCOUNTERS[_kind],
            None,
            _set(f"vehicle.{_chaser}.planner.rate_hz", 0.5),
        )


# the metrics thresholds act on the run's metrics report (the log's ``metrics`` metadata): field ->
# (its changed value [m], the kite clearance flag it turns off). The kite passes about 23 m off
# and 3 m above the quadrotor, inside every default volume.
REPORT = {
    "metrics.well_clear_horizontal": (10.0, "lowc"),
    "metrics.well_clear_vertical": (1.0, "lowc"),
    "metrics.nmac_horizontal": (10.0, "nmac"),
    "metrics.nmac_vertical": (1.0, "nmac"),
}


def _planner_fields() -> list[str]:
    return [f for f in schema_fields() if f.startswith("vehicle.planner<")]


LABELS |= {f: "the planner union's tag" for f in _planner_fields() if f.endswith(".type")}


def test_every_field_is_accounted_for():
    fields = set(schema_fields())
    lists: dict[str, Mapping[str, object]] = {
        "EFFECTS": EFFECTS,
        "DECISIONS": DECISIONS,
        "REPORT": REPORT,
        "LABELS": LABELS,
        "SHOWN_ELSEWHERE": SHOWN_ELSEWHERE,
    }
    placed = [f for d in lists.values() for f in d]
    twice = sorted({f for f in placed if placed.count(f) > 1})
    assert not twice, f"fields in more than one list: {twice}"
    assert not RECORDS_ONLY - DECISIONS.keys(), "records-only options must be planner options"
    assert not sorted(fields - set(placed)), "fields with no shown effect and no label"
    assert not sorted(set(placed) - fields), "listed fields that are not in the schema"


def test_tests_named_as_showing_a_field_exist():
    named = {ref for where in SHOWN_ELSEWHERE.values() for ref in re.findall(r"(tests/\w+\.py)(?:::(\w+))?", where)}
    for file, test in sorted(named):
        assert (ROOT / file).is_file(), file
        assert not test or re.search(rf"^def {test}\(", (ROOT / file).read_text(), re.M), f"{file}::{test}"


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


class _Records:
    """Stands in for the run log of a planner's own records: keeps each record (topic, sim time,
    payload) with the planner type's wall-clock fields left out."""

    epoch_ns = 0

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self.out: list[tuple] = []

    def write_json(self, topic: str, t: float, payload: dict, *_schema: object) -> None:
        payload = copy.deepcopy(payload)
        for dotted in WALLCLOCK_FIELDS.get(self.kind, {}).get(topic.split("/plan", 1)[1], ()):
            *head, last = dotted.split(".")
            node = payload
            for part in head:
                node = node.get(part, {})
            node.pop(last, None)
        self.out.append((topic, t, json.dumps(payload, sort_keys=True, default=str)))

    def write_proto(self, topic: str, t: float, message: typing.Any, *_metadata: object) -> None:
        self.out.append((topic, t, message.SerializeToString(deterministic=True)))


def _decisions(path: Path, data: dict, vehicle: str) -> tuple[RerunReport, list[tuple]]:
    """``vehicle``'s planner built from the scenario ``data`` as the runner builds it, re-run on
    the log at ``path``: the report against the logged plans, and every new plan and record."""
    scenario = sc.parse_scenario(data, "decisions")
    cfg = next(v for v in scenario.vehicle if v.name == vehicle)
    af = get_airframe(cfg.aircraft)
    gains = af.make_controller(cfg.gains).gains
    records = PLANNERS[cfg.planner.type].records
    log = _Records(cfg.planner.type)
    sink = RecordSink(typing.cast(typing.Any, log), f"/{vehicle}/plan", scenario.origin_point)

    class Recorded:
        def __init__(self, inner: Planner) -> None:
            self.inner, self.name = inner, inner.name

        def plan(self, estimate: VehicleState, threats: Threats, t: float) -> Plan:
            p = self.inner.plan(estimate, threats, t)
            if p.t == t:
                log.out.append(
                    ("plan", t, p.status.value, p.positions.tobytes(), p.times.tobytes(), p.labels.tobytes())
                )
            if records is not None:
                records(sink, self.inner, p, t)
            return p

    alt = scenario.origin_point.alt_m
    report = rerun_planner(path, vehicle, lambda m: Recorded(scenario_planner(cfg, m, af, gains, scenario.wind, alt)))
    return report, log.out


_FLOWN: dict[str, Path] = {}
_REPLAYED: dict[tuple[str, str, str], list[tuple]] = {}


def _replayed(kind: str, data: dict, vehicle: str, tmp_path_factory: pytest.TempPathFactory) -> list[tuple]:
    """Decisions of ``vehicle`` planned from ``data`` on the flown encounter ``kind`` (each
    encounter flown once per module and checked to re-run plan for plan)."""
    if kind not in _FLOWN:
        base = ENCOUNTERS[kind]
        path = tmp_path_factory.mktemp(kind) / "run.mcap"
        run_scenario(sc.parse_scenario(base, kind), path, scenario_text=tomli_w.dumps(base))
        for v in _planned(base):
            report, _ = _decisions(path, base, v)
            assert report.plans > 0 and report.differences == [], f"{kind}: {vehicle} does not re-run its plans"
        _FLOWN[kind] = path
    key = (kind, tomli_w.dumps(data), vehicle)
    if key not in _REPLAYED:
        _REPLAYED[key] = _decisions(_FLOWN[kind], data, vehicle)[1]
    return _REPLAYED[key]


def _planned(data: dict) -> list[str]:
    return [v["name"] for v in data["vehicle"] if v["planner"]["type"] != "follow_mission"]


@pytest.mark.closed_loop
@pytest.mark.parametrize("field", sorted(DECISIONS))
def test_planner_option_changes_a_decision(field, tmp_path_factory):
    kind, prepare, change = DECISIONS[field]
    before = copy.deepcopy(ENCOUNTERS[kind])
    if prepare is not None:
        prepare(before)
    after = copy.deepcopy(before)
    change(after)
    assert after != before, "the change changes nothing in the scenario"
    what = "record" if field in RECORDS_ONLY else "plan"
    assert any(
        _of(what, _replayed(kind, after, v, tmp_path_factory))
        != _of(what, _replayed(kind, before, v, tmp_path_factory))
        for v in _planned(before)
    ), f"{field}: every {what} is the same"


def _of(what: str, decisions: list[tuple]) -> list[tuple]:
    """The plans (``what`` = "plan") or the planner's own records of a re-run."""
    return [d for d in decisions if (d[0] == "plan") == (what == "plan")]


_KITE: dict[str, object] = {}


def _kite_clearance(data: dict, tmp: Path, tag: str) -> dict:
    """The quadrotor's clearance record of the kite in the run's metrics, read from its log."""
    path = tmp / f"{tag}.mcap"
    run_scenario(sc.parse_scenario(data, tag), path, scenario_text=tomli_w.dumps(data))
    metrics = json.loads(read_info(path).metadata["metrics"]["json"])
    return metrics["vehicles"]["quad"]["clearance"]["object.kite"]


@pytest.mark.closed_loop
@pytest.mark.parametrize("field", sorted(REPORT))
def test_metrics_threshold_changes_the_report(field, tmp_path):
    value, flag = REPORT[field]
    before = copy.deepcopy(_QUAD)
    before["object"][0]["altitude"] = 424.0
    if not _KITE:
        _KITE.update(_kite_clearance(before, tmp_path, "before"))
    assert _KITE["lowc"] and _KITE["nmac"], "the kite must start inside both default volumes"
    after = copy.deepcopy(before)
    _set(field, value)(after)
    assert not _kite_clearance(after, tmp_path, "after")[flag], f"{field}: the kite is still inside"
