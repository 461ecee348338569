"""Scenario files (TOML): one file = one reproducible closed-loop flight test.

Every field is validated; an error names the file and the field path, e.g.
``scenarios/x.toml: vehicle[0].mission.waypoints[2].altitude: wrong unit: 'kt' is a speed, ...``.
Quantities take a bare number in the documented unit or a string with a unit (``sim.units``).
Positions are local NED offsets from ``origin`` (north, east [m]) and altitude MSL [m].
"""

from __future__ import annotations

import tomllib
from datetime import datetime, timezone
from pathlib import Path
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from aircraft.registry import get_airframe
from sim.units import Angle, quantity

SCHEMA_VERSION = 1


class ScenarioError(ValueError):
    """A scenario file is unreadable or invalid; the message is one line naming the field."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Origin(_Strict):
    """WGS84 origin of the local NED frame; lat/lon in degrees; ``altitude`` [m MSL] is also
    the elevation of the flat ground under the whole scenario."""

    lat: quantity("angle", -90.0, 90.0)
    lon: quantity("angle", -180.0, 180.0)
    altitude: quantity("length", -500.0, 9000.0) = 0.0


_Offset = quantity("length", -2.0e6, 2.0e6)
_Altitude = quantity("length", -500.0, 30000.0)


class Waypoint(_Strict):
    """A waypoint: north/east offset from the origin [m], altitude MSL [m]; a multirotor hovers
    ``hold`` [s] there."""

    north: _Offset
    east: _Offset
    altitude: _Altitude
    hold: quantity("time", 0.0, 86400.0) = 0.0
    yaw: Angle | None = None  # multirotor heading at this waypoint (default: along the path)


class Mission(_Strict):
    """Waypoints flown in order at ``cruise_speed`` (true airspeed for fixed wing)."""

    cruise_speed: quantity("speed", 0.0, 120.0, lo_open=True)
    acceptance_radius: quantity("length", 0.0, 5000.0, lo_open=True) = 100.0
    waypoints: Annotated[list[Waypoint], Field(min_length=1)]
    land: bool = False
    # multirotor guidance: "path" flies the legs at cruise speed; "step" jumps the position
    # setpoint to each waypoint in turn (step-response tests, position-mode "go to")
    guidance: Literal["path", "step"] = "path"


class Initial(_Strict):
    """Initial state: NED offset from the origin [m], altitude MSL [m], TAS [m/s], heading."""

    north: _Offset = 0.0
    east: _Offset = 0.0
    altitude: _Altitude
    airspeed: quantity("speed", 0.0, 120.0) = 0.0
    heading: Angle = 0.0
    roll: quantity("angle", -90.0, 90.0) = 0.0
    pitch: quantity("angle", -90.0, 90.0) = 0.0
    trim: bool | None = None  # default: JSBSim trim for fixed wing; multirotors start in hover
    on_ground: bool = False


class PlannerConfig(_Strict):
    type: Literal["follow_mission"] = "follow_mission"
    rate_hz: Annotated[float, Field(gt=0.0, le=100.0)] = 1.0


class Vehicle(_Strict):
    name: Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_]*$")]
    aircraft: str
    gains: Path | None = None
    initial: Initial
    mission: Mission
    planner: PlannerConfig = PlannerConfig()

    @field_validator("aircraft")
    @classmethod
    def _known_aircraft(cls, v: str) -> str:
        try:
            get_airframe(v)
        except KeyError as exc:
            raise ValueError(exc.args[0]) from None
        return v

    @model_validator(mode="after")
    def _fits_airframe(self) -> "Vehicle":
        kind = get_airframe(self.aircraft).kind
        if kind == "multirotor":
            if self.initial.trim:
                raise ValueError("initial.trim: JSBSim cannot trim a multirotor; it starts in hover "
                                 "(or on the ground) and its controller holds it")
            return self
        if self.mission.land:
            raise ValueError(f"mission.land: only multirotors land at the end of a mission ({self.aircraft} is {kind})")
        if self.initial.on_ground:
            raise ValueError(f"initial.on_ground: {self.aircraft} ({kind}) starts in the air")
        if any(w.hold > 0 or w.yaw is not None for w in self.mission.waypoints):
            raise ValueError(f"mission.waypoints: hold and yaw are for multirotors ({self.aircraft} is {kind})")
        if self.mission.guidance != "path":
            raise ValueError(f"mission.guidance: step guidance is for multirotors ({self.aircraft} is {kind})")
        return self


class Mavlink(_Strict):
    """MAVLink to a ground station during the run (vehicle k: system id k+1, GCS port
    ``base_port + k``). ``pace``: at most this many times the wall clock (0: sim time, no
    waiting)."""

    enabled: bool = False
    gcs_host: str = "127.0.0.1"
    base_port: Annotated[int, Field(ge=1024, le=65000)] = 14550
    rate_hz: Annotated[float, Field(gt=0.0, le=50.0)] = 4.0
    pace: Annotated[float, Field(ge=0.0, le=1000.0)] = 1.0


class Logging(_Strict):
    rate_hz: Annotated[float, Field(gt=0.0, le=1000.0)] = 10.0


class Scenario(_Strict):
    """A validated scenario. ``seed`` fixes every random draw of the run."""

    schema_version: Literal[1] = SCHEMA_VERSION
    name: Annotated[str, Field(min_length=1)]
    description: str = ""
    seed: Annotated[int, Field(ge=0, lt=2**63)]
    duration: quantity("time", 0.0, 30 * 86400.0, lo_open=True)
    start_time: datetime = datetime(2026, 6, 21, 6, 0, tzinfo=timezone.utc)
    stop_when_complete: bool = True
    origin: Origin
    logging: Logging = Logging()
    mavlink: Mavlink = Mavlink()
    vehicle: Annotated[list[Vehicle], Field(min_length=1)]

    @field_validator("start_time")
    @classmethod
    def _utc(cls, v: datetime) -> datetime:
        if v.tzinfo is None:
            raise ValueError("start_time needs a time zone, e.g. 2026-06-21T06:00:00Z")
        return v.astimezone(timezone.utc)

    @model_validator(mode="after")
    def _unique_names(self) -> "Scenario":
        names = [v.name for v in self.vehicle]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"vehicle names must be unique, repeated: {', '.join(dup)}")
        return self

    @property
    def epoch_ns(self) -> int:
        """Log time of sim time 0 [ns since the Unix epoch]."""
        return int(self.start_time.timestamp()) * 1_000_000_000


def _field_path(loc: tuple) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out or "(top level)"


def _describe(err: dict) -> str:
    path = _field_path(err["loc"])
    kind = err["type"]
    if kind == "extra_forbidden":
        return f"{path}: unknown key"
    if kind == "missing":
        return f"{path}: missing required field"
    msg = err["msg"]
    for prefix in ("Value error, ", "Assertion failed, "):
        msg = msg.removeprefix(prefix)
    if kind in ("greater_than_equal", "less_than_equal", "greater_than", "less_than"):
        msg = f"out of range: {msg.lower()} (got {err.get('input')!r})"
    return f"{path}: {msg}"


def parse_scenario(data: dict, source: str = "<scenario>") -> Scenario:
    """Validate a scenario mapping; ScenarioError names ``source`` and the first bad field."""
    try:
        return Scenario.model_validate(data)
    except ValidationError as exc:
        errors = exc.errors(include_url=False)
        more = f" (+{len(errors) - 1} more)" if len(errors) > 1 else ""
        raise ScenarioError(f"{source}: {_describe(errors[0])}{more}") from None


def load_scenario(path: str | Path) -> tuple[Scenario, str]:
    """Read and validate a TOML scenario; returns it with the file's text (kept in the log)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot read scenario file ({exc.strerror})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{path}: not valid TOML: {exc}") from None
    return parse_scenario(data, str(path)), text

