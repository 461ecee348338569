"""Scenario files (TOML): one file = one reproducible closed-loop flight test.

Every field is validated; an error names the file and the field path, e.g.
``scenarios/x.toml: vehicle[0].mission.waypoints[2].altitude: wrong unit: 'kt' is a speed, ...``.
Quantities take a bare number in the documented unit or a string with a unit (``sim.units``).
Positions are local NED offsets from ``origin`` (north, east [m]) and altitude MSL [m].
"""

from __future__ import annotations

import itertools
import math
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Final, Literal, Union

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    create_model,
    field_validator,
    model_validator,
)
from pydantic_core import ErrorDetails
from shapely.geometry import Polygon

from aircraft.registry import get_airframe
from sim.estimation.sensor_estimator import SensorEstimatorConfig
from sim.geodesy import GeoPoint
from sim.input_files import parse_toml, read_text
from sim.planner_registry import PLANNERS, PlannerType
from sim.sensors import isa
from sim.sensors.airspeed import AirspeedConfig
from sim.sensors.baro import BaroConfig
from sim.sensors.config import SensorConfigError
from sim.sensors.gnss import GnssConfig
from sim.sensors.imu import ImuConfig
from sim.sensors.lidar import LidarConfig
from sim.sensors.magnetometer import MagnetometerConfig
from sim.sensors.presets import PRESETS
from sim.units import Angle, Speed, quantity

SCHEMA_VERSION: Final = 1
# MCAP log times are unsigned 64-bit nanoseconds since the Unix epoch: a run lies between these
LOG_TIME_MIN = datetime(1970, 1, 1, tzinfo=UTC)
LOG_TIME_MAX = LOG_TIME_MIN + timedelta(microseconds=2**64 // 1000)
# a scenario/batch name: it names files (logs/<name>.mcap), so no path separators, no leading dot
NAME_PATTERN = r"^[^/\\\x00-\x1f\x7f.][^/\\\x00-\x1f\x7f]*$"


class ScenarioError(ValueError):
    """A scenario file is unreadable or invalid; the message is one line naming the field."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Origin(_Strict):
    """WGS84 origin of the local NED frame; lat/lon in degrees; ``altitude`` [m MSL] is also
    the elevation of the flat ground under the whole scenario."""

    lat: Annotated[float, quantity("angle", -90.0, 90.0)]
    lon: Annotated[float, quantity("angle", -180.0, 180.0)]
    altitude: Annotated[float, quantity("length", -500.0, 9000.0)] = 0.0


_Offset = Annotated[float, quantity("length", -2.0e6, 2.0e6)]
_Altitude = Annotated[float, quantity("length", -500.0, 30000.0)]


class Waypoint(_Strict):
    """A waypoint: north/east offset from the origin [m], altitude MSL [m]; a multirotor hovers
    ``hold`` [s] there."""

    north: _Offset
    east: _Offset
    altitude: _Altitude
    hold: Annotated[float, quantity("time", 0.0, 86400.0)] = 0.0
    yaw: Angle | None = None  # multirotor heading at this waypoint (default: along the path)


class MissionSpec(_Strict):
    """Waypoints flown in order at ``cruise_speed`` (true airspeed for fixed wing)."""

    cruise_speed: Annotated[float, quantity("speed", 0.0, 120.0, lo_open=True)]
    acceptance_radius: Annotated[float, quantity("length", 0.0, 5000.0, lo_open=True)] = 100.0
    waypoints: Annotated[list[Waypoint], Field(min_length=1)]
    land: bool = False
    # multirotor guidance: "path" flies the legs at cruise speed; "step" jumps the position
    # setpoint to each waypoint in turn (step-response tests, position-mode "go to")
    guidance: Literal["path", "step"] = "path"
    # fixed wing: after the last waypoint fly the waypoints again from the first (station
    # keeping); the mission then never completes and the run lasts its duration
    repeat: bool = False


REPEAT_PLANNERS: Final = ("follow_mission", "mptp")  # planners that plan leg by leg, so may fly a mission again


class Initial(_Strict):
    """Initial state: NED offset from the origin [m], altitude MSL [m], TAS [m/s], heading."""

    north: _Offset = 0.0
    east: _Offset = 0.0
    altitude: _Altitude
    airspeed: Annotated[float, quantity("speed", 0.0, 120.0)] = 0.0
    heading: Angle = 0.0
    roll: Annotated[float, quantity("angle", -90.0, 90.0)] = 0.0
    pitch: Annotated[float, quantity("angle", -90.0, 90.0)] = 0.0
    trim: bool | None = None  # default: JSBSim trim for fixed wing; multirotors start in hover
    on_ground: bool = False


class AltitudeScheduleConfig(_Strict):
    """Energy management by altitude (sim/energy/altitude_schedule.py): climb to ``ceiling`` once
    the battery reaches ``soc_high``, glide down to ``floor`` once it falls to ``soc_low``; the
    mission's waypoint altitudes are replaced by this demand (fixed wing)."""

    floor: _Altitude
    ceiling: _Altitude
    soc_high: Annotated[float, Field(ge=0.0, le=1.0)] = 0.95
    soc_low: Annotated[float, Field(ge=0.0, le=1.0)] = 0.90

    @model_validator(mode="after")
    def _ordered(self) -> AltitudeScheduleConfig:
        if not self.floor < self.ceiling:
            raise ValueError("floor must be below ceiling")
        if not self.soc_low < self.soc_high:
            raise ValueError("soc_low must be below soc_high")
        return self


class EnergyOptions(_Strict):
    """Electrical power system of an airframe that has one (``aircraft/<name>/energy.toml``):
    ``enabled`` false flies without it; ``initial_soc`` overrides the file's starting state of
    charge [0..1]; ``altitude_schedule`` turns on energy management by altitude."""

    enabled: bool = True
    initial_soc: Annotated[float, Field(ge=0.0, le=1.0)] | None = None
    altitude_schedule: AltitudeScheduleConfig | None = None


class _PlannerBase(_Strict):
    rate_hz: Annotated[float, Field(gt=0.0, le=100.0)] = 1.0
    if TYPE_CHECKING:  # fields of each planner type's model (_planner_model)
        type: str
        options: BaseModel


def _planner_model(entry: PlannerType) -> type[_PlannerBase]:
    """``[vehicle.planner]`` of one planner type: ``type``, ``rate_hz`` [Hz] and ``options``,
    the type's own options model (``sim.planner_registry``)."""
    required = any(f.is_required() for f in entry.options.model_fields.values())
    options: object = ... if required else Field(default_factory=entry.options)
    return create_model(
        f"{entry.name.title().replace('_', '')}Planner",
        __base__=_PlannerBase,
        type=(Literal[entry.name], entry.name),
        options=(entry.options, options),
    )


_PLANNER_MODELS = {name: _planner_model(entry) for name, entry in PLANNERS.items()}
# ``type`` picks the model (follow_mission when not given); errors name the options' fields
if TYPE_CHECKING:  # the union is built at run time; statically, every member is a _PlannerBase
    PlannerConfig = _PlannerBase
else:
    PlannerConfig = Annotated[Union[tuple(_PLANNER_MODELS.values())], Field(discriminator="type")]  # noqa: UP007


class SensorsSpec(_Strict):
    """``[vehicle.sensors]`` (the ``ekf`` estimator's sensor models): ``preset`` (``consumer``,
    ``tactical``; ``sim/sensors/presets.py``) and per-sensor tables ``imu``, ``gnss``, ``baro``,
    ``airspeed``, ``mag`` whose fields override the preset's: ``rate_hz``, ``latency_s``,
    ``dropout`` (probability a sample is lost) and the sensor's error model — white noise, turn-on
    bias (``*_bias_init_std``), in-run instability (``*_bias_rw``, a bias random walk), scale
    factor, quantisation (fields and units: ``sim/sensors/<sensor>.py``). Rates not given are the
    airframe kind's (``SensorEstimatorConfig.for_kind``)."""

    preset: Literal["consumer", "tactical"] = "consumer"
    imu: ImuConfig | None = None
    gnss: GnssConfig | None = None
    baro: BaroConfig | None = None
    airspeed: AirspeedConfig | None = None
    mag: MagnetometerConfig | None = None

    @model_validator(mode="before")
    @classmethod
    def _preset_under_tables(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        out = dict(data)
        for sensor, values in PRESETS.get(data.get("preset", "consumer"), {}).items():
            out[sensor] = values | dict(data.get(sensor) or {})
        return out

    def estimator_config(self, kind: Literal["fixed_wing", "multirotor"]) -> SensorEstimatorConfig:
        """The airframe kind's sensor suite with the given fields (preset and tables) replaced."""
        base = SensorEstimatorConfig.for_kind(kind)
        update = {}
        for name in ("imu", "gnss", "baro", "airspeed", "mag"):
            given, default = getattr(self, name), getattr(base.sensors, name)
            if given is not None and default is not None:
                update[name] = type(default).model_validate(_merged(default.model_dump(), _given(given)))
        return base.model_copy(update={"sensors": base.sensors.model_copy(update=update)})


def _given(model: BaseModel) -> dict[str, Any]:
    """The fields set explicitly (nested models: their explicitly set fields)."""
    out: dict[str, Any] = {}
    for name in model.model_fields_set:
        value = getattr(model, name)
        out[name] = _given(value) if isinstance(value, BaseModel) else value
    return out


def _merged(base: dict[str, Any], given: dict[str, Any]) -> dict[str, Any]:
    """``base`` with ``given`` laid over it, nested tables merged key by key."""
    out = dict(base)
    for k, v in given.items():
        out[k] = _merged(base[k], v) if isinstance(v, dict) and isinstance(base.get(k), dict) else v
    return out


_Time = Annotated[float, quantity("time", 0.0, 30 * 86400.0)]


class Outage(_Strict):
    """A window of sim time [start, end) in which a vehicle's C2/UTM link carries nothing."""

    start: _Time
    end: _Time

    @model_validator(mode="after")
    def _ordered(self) -> Outage:
        if not self.end > self.start:
            raise ValueError(f"end ({self.end:g} s) must be after start ({self.start:g} s)")
        return self


class UtmLink(_Strict):
    """A vehicle's radio link (``sim/utm_link.py``): one-way ``latency``, message ``loss``
    probability, ``outage`` windows. As ``utm_link``: its C2/UTM link to the authority, both
    directions (a vehicle without one has an ideal link). As ``peer_link``: its
    vehicle-to-vehicle link (``sim/peer_link.py``), what it sends and (outages) receives; only
    vehicles with one talk to each other (response mode). Both need the ``[utm]`` section."""

    latency: Annotated[float, quantity("time", 0.0, 60.0)] = 0.0
    loss: Annotated[float, Field(ge=0.0, lt=1.0)] = 0.0
    outage: list[Outage] = []


class VehicleSpec(_Strict):
    name: Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_]*$")]
    aircraft: str
    gains: Path | None = None
    # "ekf": sensor models + INS/GNSS EKF, the loop closes on estimates; "perfect": ideal sensors
    estimator: Literal["ekf", "perfect"] = "ekf"
    # a scanning LiDAR for the planners (sim/sensors/lidar.py LidarConfig fields; ~4 ms a
    # 21,960-ray scan, so opt-in)
    lidar: LidarConfig | None = None
    sensors: SensorsSpec = SensorsSpec()
    initial: Initial
    mission: MissionSpec
    planner: PlannerConfig = Field(default_factory=_PLANNER_MODELS["follow_mission"])
    energy: EnergyOptions = EnergyOptions()
    utm_link: UtmLink | None = None
    peer_link: UtmLink | None = None

    @model_validator(mode="before")
    @classmethod
    def _default_planner_type(cls, data: Any) -> Any:
        planner = data.get("planner") if isinstance(data, dict) else None
        if isinstance(planner, dict) and "type" not in planner:
            data = {**data, "planner": {"type": "follow_mission", **planner}}
        return data

    @field_validator("aircraft")
    @classmethod
    def _known_aircraft(cls, v: str) -> str:
        try:
            get_airframe(v)
        except KeyError as exc:
            raise ValueError(exc.args[0]) from None
        return v

    @model_validator(mode="after")
    def _fits_airframe(self) -> VehicleSpec:
        kind = get_airframe(self.aircraft).kind
        entry = PLANNERS[self.planner.type]
        if kind not in entry.airframes:
            raise ValueError(
                f"planner: {entry.name} planner does not fly a {kind} (it flies: {', '.join(entry.airframes)})"
            )
        e = self.energy
        if (e.initial_soc is not None or e.altitude_schedule is not None) and (
            get_airframe(self.aircraft).energy_file is None or not e.enabled
        ):
            raise ValueError(f"energy: {self.aircraft} flies without a power-system model here (energy.toml, enabled)")
        if self.lidar is not None and entry.sensing_range is not None:
            need = entry.sensing_range(self.planner.options, kind, self.mission.cruise_speed)
            if self.lidar.max_range_m < need:
                raise ValueError(
                    f"lidar.max_range_m: {self.lidar.max_range_m:g} m does not cover the reach-set grid "
                    f"({need:g} m at this cruise speed and period); cells beyond the range are Uncertain "
                    "and block every path"
                )
        af = get_airframe(self.aircraft)
        if kind == "multirotor" and self.sensors.airspeed is not None:
            raise ValueError(f"sensors.airspeed: a multirotor carries no pitot ({self.aircraft})")
        try:
            self.sensors.estimator_config(kind).check_rates(af.plant_hz)
        except SensorConfigError as exc:
            raise ValueError(f"sensors: {exc}") from None
        if kind == "multirotor":
            if self.initial.trim:
                raise ValueError(
                    "initial.trim: JSBSim cannot trim a multirotor; it starts in hover "
                    "(or on the ground) and its controller holds it"
                )
            if self.mission.repeat:
                raise ValueError(f"mission.repeat: for fixed wing ({self.aircraft} is {kind})")
            return self
        if self.mission.repeat and self.planner.type not in REPEAT_PLANNERS:
            raise ValueError(f"mission.repeat: only with the {' or '.join(REPEAT_PLANNERS)} planner")
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
    waiting). Only the ground station ``gcs_system_id`` (component ``gcs_component_id``, any if
    unset) is obeyed, after its heartbeat. ``bind_host``: local interface (default loopback; a
    non-loopback ``gcs_host`` needs it set). ``signing_key_file``: a file holding the MAVLink 2
    signing passphrase (relative to the scenario file; signing off if unset). ``max_height``
    above the ground and ``max_range`` from the origin bound the mission items and position
    targets a GCS may send (defaults by airframe kind, ``sim/mavlink/envelope.py``)."""

    enabled: bool = False
    gcs_host: str = "127.0.0.1"
    base_port: Annotated[int, Field(ge=1024, le=65000)] = 14550
    rate_hz: Annotated[float, Field(gt=0.0, le=50.0)] = 4.0
    pace: Annotated[float, Field(ge=0.0, le=1000.0)] = 1.0
    gcs_system_id: Annotated[int, Field(ge=1, le=255)] = 255
    gcs_component_id: Annotated[int, Field(ge=0, le=255)] | None = None
    bind_host: str | None = None
    signing_key_file: Path | None = None
    max_height: Annotated[float, quantity("length", 0.0, 30500.0, lo_open=True)] | None = None
    max_range: Annotated[float, quantity("length", 0.0, 3.0e6, lo_open=True)] | None = None

    @field_validator("signing_key_file")
    @classmethod
    def _relative_to_scenario(cls, v: Path | None, info: ValidationInfo) -> Path | None:
        return None if v is None else Path((info.context or {}).get("base_dir", ".")) / v


class WindLevel(_Strict):
    """One row of a wind profile: altitude MSL [m] and the horizontal wind there, NED [m/s]."""

    altitude: _Altitude
    north: Speed = 0.0
    east: Speed = 0.0


def _profile_rows(levels: list[WindLevel]) -> list[WindLevel]:
    alts = [lv.altitude for lv in levels]
    if any(b <= a for a, b in itertools.pairwise(alts)):
        raise ValueError(f"altitudes must increase strictly, got {[round(a, 1) for a in alts]} m")
    return levels


class WindHour(_Strict):
    """A wind profile valid at ``time`` [s after the start]; profiles are interpolated in time."""

    time: Annotated[float, quantity("time", 0.0, 30 * 86400.0)]
    levels: Annotated[list[WindLevel], Field(min_length=2)]

    @field_validator("levels")
    @classmethod
    def _increasing(cls, v: list[WindLevel]) -> list[WindLevel]:
        return _profile_rows(v)


class Wind(_Strict):
    """Wind: velocity of the air mass, NED [m/s] (``north = 5`` blows towards north) = the steady
    vector (``north``, ``east``, ``down``) + a profile with altitude: ``levels`` (a table,
    interpolated linearly, held constant beyond its ends), ``hours`` (tables at times, interpolated
    in time) or ``standard`` (a named profile, ``sim.wind_field``); at most one of the three.
    Turbulence: MIL-F-8785C Dryden (JSBSim's Milspec model; seeded from the scenario)."""

    north: Speed = 0.0
    east: Speed = 0.0
    down: Speed = 0.0
    turbulence: Literal["none", "light", "moderate", "severe"] = "none"
    levels: list[WindLevel] = []
    hours: list[WindHour] = []
    standard: Literal["midlatitude_jet"] | None = None

    @field_validator("levels")
    @classmethod
    def _increasing(cls, v: list[WindLevel]) -> list[WindLevel]:
        if len(v) == 1:
            raise ValueError("a profile needs at least 2 levels")
        return _profile_rows(v) if v else v

    @field_validator("hours")
    @classmethod
    def _times(cls, v: list[WindHour]) -> list[WindHour]:
        times = [h.time for h in v]
        if any(b <= a for a, b in itertools.pairwise(times)):
            raise ValueError(f"times must increase strictly, got {times} s")
        return v

    @model_validator(mode="after")
    def _one_profile(self) -> Wind:
        given = [k for k in ("levels", "hours", "standard") if getattr(self, k)]
        if len(given) > 1:
            raise ValueError(f"{given[1]}: give one wind profile, not {' and '.join(given)}")
        return self


class Obstacle(_Strict):
    """A static obstacle: a footprint extruded from ``base`` to ``top`` (altitudes MSL [m];
    ``base`` defaults to the ground = origin altitude). Shapes: ``box`` (centre north/east,
    ``length`` along ``heading``, ``width`` across), ``cylinder`` (centre, ``radius``),
    ``polygon`` (``points`` = [[north, east], ...] [m])."""

    id: Annotated[str, Field(min_length=1)]
    shape: Literal["box", "cylinder", "polygon"]
    north: _Offset = 0.0
    east: _Offset = 0.0
    length: Annotated[float, quantity("length", 0.0, 1e5, lo_open=True)] | None = None
    width: Annotated[float, quantity("length", 0.0, 1e5, lo_open=True)] | None = None
    heading: Angle = 0.0
    radius: Annotated[float, quantity("length", 0.0, 1e5, lo_open=True)] | None = None
    points: list[tuple[float, float]] | None = None
    base: _Altitude | None = None
    top: _Altitude

    @model_validator(mode="after")
    def _shape_fields(self) -> Obstacle:
        need = {"box": ("length", "width"), "cylinder": ("radius",), "polygon": ("points",)}[self.shape]
        missing = [f for f in need if getattr(self, f) is None]
        if missing:
            raise ValueError(f"{missing[0]}: a {self.shape} needs {' and '.join(need)}")
        if self.shape == "polygon":
            _simple_polygon(self.points)
        if self.base is not None and self.top <= self.base:
            raise ValueError(f"top: {self.top:g} m is not above its base {self.base:g} m")
        return self


class GeofenceSpec(_Strict):
    """An area with an altitude band (MSL [m]) the vehicles must stay in (``keep_in``) or out of."""

    id: Annotated[str, Field(min_length=1)]
    points: list[tuple[float, float]]
    floor: _Altitude = -500.0
    ceiling: _Altitude = 30000.0
    keep_in: bool = True

    @field_validator("points")
    @classmethod
    def _simple(cls, v):
        return _simple_polygon(v)


def _simple_polygon(points):
    """``points`` if they make a simple polygon of >= 3 [north, east] vertices, else ValueError."""
    if len(points) < 3:
        raise ValueError("points: a polygon needs at least 3 [north, east] points")
    if not Polygon(points).is_valid:
        raise ValueError("points: the polygon is not simple (its edges cross)")
    return points


class Velocity(_Strict):
    north: Speed = 0.0
    east: Speed = 0.0
    down: Speed = 0.0


class TrafficObject(_Strict):
    """Scripted traffic that is not flown by JSBSim: a sphere of ``radius`` [m] at ``north``,
    ``east``, ``altitude`` (MSL) at time ``appear`` [s], moving at constant ``velocity`` NED
    [m/s] (zero: a static threat). ``cooperative`` ones broadcast their position."""

    id: Annotated[str, Field(min_length=1)]
    radius: Annotated[float, quantity("length", 0.0, 1e4, lo_open=True)]
    north: _Offset
    east: _Offset
    altitude: _Altitude
    velocity: Velocity = Velocity()
    appear: Annotated[float, quantity("time", 0.0, 30 * 86400.0)] = 0.0
    cooperative: bool = False


class Surveillance(_Strict):
    """How each vehicle senses the traffic (the other vehicles and the objects): position
    reports (ADS-B for cooperative traffic, a surveillance sensor of the same error model for
    the rest) at ``rate_hz`` with ``latency``, ``dropout`` probability, position noise (std,
    horizontal/vertical) and velocity noise; a constant-velocity Kalman track per target."""

    rate_hz: Annotated[float, Field(gt=0.0, le=50.0)] = 2.0
    latency: Annotated[float, quantity("time", 0.0, 60.0)] = 0.5
    dropout: Annotated[float, Field(ge=0.0, lt=1.0)] = 0.05
    position_noise_horizontal: Annotated[float, quantity("length", 0.0, 1e4)] = 3.0
    position_noise_vertical: Annotated[float, quantity("length", 0.0, 1e4)] = 5.0
    velocity_noise: Speed = 0.5


class _StormExtent(_Strict):
    """Vertical extent of storm cells: ``base`` and ``top`` altitudes MSL [m]; no base = from the
    ground, no top = unbounded (a cell is the prism of its outline between them)."""

    base: _Altitude | None = None
    top: _Altitude | None = None

    @model_validator(mode="after")
    def _top_above_base(self) -> _StormExtent:
        if self.base is not None and self.top is not None and not self.top > self.base:
            raise ValueError(f"top ({self.top:g} m) must be above base ({self.base:g} m)")
        return self

    def extent_up(self, origin_alt_m: float) -> tuple[float, float]:
        """[base, top] heights above the origin [m] (-inf / inf where not given)."""
        base = -math.inf if self.base is None else self.base - origin_alt_m
        return base, math.inf if self.top is None else self.top - origin_alt_m


class StormCell(_StormExtent):
    """A scripted storm cell (not drawn by the generator): polygon ``points`` [[north, east], ...]
    [m] at t = 0, drifting at constant (``drift_north``, ``drift_east``) [m/s], between ``base``
    and ``top`` (altitudes MSL [m]; default from the ground up without a top)."""

    points: list[tuple[float, float]]
    drift_north: Speed = 0.0
    drift_east: Speed = 0.0

    @field_validator("points")
    @classmethod
    def _simple(cls, v):
        return _simple_polygon(v)


class Weather(_StormExtent):
    """Synthetic convective weather (seeded from the scenario): ``cells`` storm cells over a
    box of ``size`` x ``size`` [m] south-west-cornered at the origin, drifting at
    (``drift_north``, ``drift_east``) [m/s] +- ``drift_spread``, mean radius ``radius``, between
    ``base`` and ``top`` (altitudes MSL [m]; default from the ground up without a top); a
    nowcast of the next ``horizon`` in ``step`` slices is issued every ``nowcast_period`` (what
    the vehicles see). ``seed``: the field's own seed (default: drawn from the scenario seed);
    ``pop_up``: cells may be born after the start (unforeseen by earlier nowcasts); false = every
    cell is alive at the start. ``storm``: scripted cells added to the generated ones
    (``[[weather.storm]]``). ``nowcast_files``: nowcast GeoJSON files (format in docs/mptp.md;
    paths relative to the scenario file), one per issue, instead of the synthetic and scripted
    cells: each is issued to the vehicles at its first step's time, and the truth (log and
    metrics) is the latest issued nowcast's first step (its analysis) moved by its cell
    velocities."""

    cells: Annotated[int, Field(ge=0, le=500)] = 12
    size: Annotated[float, quantity("length", 1000.0, 2e6)] = 250_000.0
    drift_north: Speed = 0.0
    drift_east: Speed = 10.0
    drift_spread: Speed = 3.0
    radius: Annotated[float, quantity("length", 100.0, 2e5)] = 8000.0
    split_probability: Annotated[float, Field(ge=0.0, le=1.0)] = 0.3
    life: Annotated[float, quantity("time", 60.0, 86400.0)] = 5400.0
    nowcast_period: Annotated[float, quantity("time", 10.0, 86400.0)] = 300.0
    horizon: Annotated[float, quantity("time", 60.0, 86400.0)] = 3600.0
    step: Annotated[float, quantity("time", 10.0, 86400.0)] = 300.0
    centres: list[tuple[float, float]] | None = None  # [[north, east], ...] [m] to place the cells
    seed: Annotated[int, Field(ge=0)] | None = None
    pop_up: bool = True
    storm: list[StormCell] = []
    nowcast_files: list[str] = []

    @field_validator("nowcast_files")
    @classmethod
    def _resolved(cls, v: list[str], info: ValidationInfo) -> list[str]:
        base = Path((info.context or {}).get("base_dir", "."))
        paths = [base / p for p in v]
        missing = [str(p) for p in paths if not p.is_file()]
        if missing:
            raise ValueError(f"no such file: {missing[0]}")
        return [str(p.resolve()) for p in paths]

    @model_validator(mode="after")
    def _one_source(self) -> Weather:
        mixed = self.nowcast_files and ({"cells", "storm", "centres", "base", "top"} & self.model_fields_set)
        if mixed:
            raise ValueError(
                f"nowcast_files replace the synthetic and scripted cells: remove {', '.join(sorted(mixed))}"
            )
        return self


class _Fault(_Strict):
    vehicle: str
    at: Annotated[float, quantity("time", 0.0, 30 * 86400.0)]
    duration: Annotated[float, quantity("time", 0.0, 30 * 86400.0, lo_open=True)] | None = None  # None: to the end


class GnssLoss(_Fault):
    kind: Literal["gnss_loss"]


class SensorBias(_Fault):
    """A bias step added to a sensor's output, in the sensor's units (per axis or scalar)."""

    kind: Literal["sensor_bias"]
    sensor: Literal["accel", "gyro", "gnss", "baro", "airspeed", "mag"]
    bias: float | list[float]


class SensorStuck(_Fault):
    kind: Literal["sensor_stuck"]
    sensor: Literal["accel", "gyro", "gnss", "baro", "airspeed", "mag"]


class MotorFailure(_Fault):
    kind: Literal["motor_failure"]
    engine: Annotated[int, Field(ge=0, le=16)]


class Gust(_Fault):
    """A 1-cosine gust: air-mass velocity NED [m/s] ramped in over ``ramp``, held, ramped out."""

    kind: Literal["gust"]
    north: Speed = 0.0
    east: Speed = 0.0
    down: Speed = 0.0
    ramp: Annotated[float, quantity("time", 0.0, 600.0)] = 2.0


Fault = Annotated[GnssLoss | SensorBias | SensorStuck | MotorFailure | Gust, Field(discriminator="kind")]


class UtmSpoof(_Strict):
    """A forged head-on case injected into ``vehicle``'s directives from ``at`` for ``duration``
    (None: to the end): a case with ``peer`` (which need not exist) at the collision point
    ``north``/``east``/``altitude`` (MSL) with ``margin``. Anti-spoofing tests: the vehicle must
    not obey it until its own surveillance confirms the peer."""

    vehicle: str
    peer: Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_]*$")]
    at: _Time
    duration: Annotated[float, quantity("time", 0.0, 30 * 86400.0, lo_open=True)] | None = None
    north: _Offset
    east: _Offset
    altitude: _Altitude
    margin: Annotated[float, quantity("length", 0.0, 1e5, lo_open=True)] = 50.0


class UtmMandate(_Strict):
    """A mandate of the authority (spec §7.1, never broken; ``avoidance/utm/mandate.py``):
    ``vehicle`` must keep clear of the cylinder of ``radius`` around ``north``/``east`` between
    ``altitude_min`` and ``altitude_max`` (MSL; unbounded when left out) from ``at`` for
    ``duration`` (None: to the end). ``id`` names it in the directives and acknowledgements."""

    id: Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_]*$")]
    vehicle: str
    at: _Time
    duration: Annotated[float, quantity("time", 0.0, 30 * 86400.0, lo_open=True)] | None = None
    north: _Offset
    east: _Offset
    radius: Annotated[float, quantity("length", 0.0, 1e5, lo_open=True)]
    altitude_min: _Altitude | None = None
    altitude_max: _Altitude | None = None

    @model_validator(mode="after")
    def _band(self) -> UtmMandate:
        lo, hi = self.altitude_min, self.altitude_max
        if lo is not None and hi is not None and not hi > lo:
            raise ValueError(f"altitude_max ({hi:g} m) must be above altitude_min ({lo:g} m)")
        return self


def _require_unique(ids: list[str], rule: str) -> None:
    """Raise the one-line error ``<rule>, repeated: <ids>`` when ``ids`` repeat an entry."""
    dup = sorted({i for i in ids if ids.count(i) > 1})
    if dup:
        raise ValueError(f"{rule}, repeated: {', '.join(dup)}")


class UtmCluster(_Strict):
    """A static airspace cluster with its own authority (spec §7.1): the horizontal box
    ``east_min`` <= east < ``east_max``, ``north_min`` <= north < ``north_max`` (offsets from the
    origin [m], every altitude). ``id`` names it on the ``/utm`` topics."""

    id: Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_]*$")]
    east_min: _Offset
    east_max: _Offset
    north_min: _Offset
    north_max: _Offset

    @model_validator(mode="after")
    def _box(self) -> UtmCluster:
        for axis in ("east", "north"):
            lo, hi = getattr(self, f"{axis}_min"), getattr(self, f"{axis}_max")
            if not hi > lo:
                raise ValueError(f"{axis}_max ({hi:g} m) must be above {axis}_min ({lo:g} m)")
        return self

    def contains(self, east: float, north: float, grow: float = 0.0) -> bool:
        """Whether the point (offsets [m]) lies in the box grown by ``grow`` [m] on every side."""
        in_east = self.east_min - grow <= east < self.east_max + grow
        return in_east and self.north_min - grow <= north < self.north_max + grow

    def overlaps(self, o: UtmCluster) -> bool:
        return (
            self.east_min < o.east_max
            and o.east_min < self.east_max
            and self.north_min < o.north_max
            and o.north_min < self.north_max
        )


class Utm(_Strict):
    """The central UTM authority (``sim/utm_authority.py``): decision ``frame`` period; a link is
    lost after ``lost_after`` without a message (the authority drops a silent vehicle from its
    cases; a vehicle without directives flies blind, the rules of the air on its own tracks);
    ``spoof``: forged cases (:class:`UtmSpoof`); ``weather``: the weather service's nowcasts go
    to the authority instead of the vehicles, and it sends each vehicle the weather cases of the
    cells its filed route crosses in its directives (§7.5; needs ``[weather]``); ``mandate``:
    mandates sent in the directives (:class:`UtmMandate`); ``cluster``: static airspace clusters,
    one authority each (:class:`UtmCluster`; none: one authority over the whole airspace), a
    vehicle directed by the one whose box holds its notified position, notifying every one whose
    box grown by ``handover`` [m] holds it (so the cases of a pair across a boundary are known on
    both sides before either vehicle crosses); outside every box the airspace is uncontrolled
    (no directives: blind mode)."""

    frame: Annotated[float, quantity("time", 0.0, 60.0, lo_open=True)] = 1.0
    lost_after: Annotated[float, quantity("time", 0.0, 600.0, lo_open=True)] = 3.0
    spoof: list[UtmSpoof] = []
    weather: bool = False
    mandate: list[UtmMandate] = []
    cluster: list[UtmCluster] = []
    handover: Annotated[float, quantity("length", 0.0, 1e5)] = 300.0

    @model_validator(mode="after")
    def _clusters(self) -> Utm:
        ids = [c.id for c in self.cluster]
        _require_unique(ids, "utm.cluster ids must be unique")
        for i, a in enumerate(self.cluster):
            for b in self.cluster[i + 1 :]:
                if a.overlaps(b):
                    raise ValueError(f"utm.cluster {a.id!r} and {b.id!r} overlap (a position has one authority)")
        return self

    @model_validator(mode="after")
    def _lost_after_frames(self) -> Utm:
        if self.lost_after < self.frame:
            raise ValueError(f"lost_after ({self.lost_after:g} s) must be at least one frame ({self.frame:g} s)")
        return self


class Metrics(_Strict):
    """Thresholds of the run metrics: the well-clear volume between two aircraft (horizontal
    radius, vertical half height; default ASTM F3442 small-UAS well clear) and the near mid-air
    collision cylinder (default RTCA DO-365, 500 ft / 100 ft, manned-scale traffic)."""

    well_clear_horizontal: Annotated[float, quantity("length", 0.0, 1e5, lo_open=True)] = 2000 * 0.3048
    well_clear_vertical: Annotated[float, quantity("length", 0.0, 1e4, lo_open=True)] = 250 * 0.3048
    nmac_horizontal: Annotated[float, quantity("length", 0.0, 1e4, lo_open=True)] = 500 * 0.3048
    nmac_vertical: Annotated[float, quantity("length", 0.0, 1e4, lo_open=True)] = 100 * 0.3048


class Logging(_Strict):
    """``rate_hz`` [Hz] of the per-vehicle topics; ``encoding``: ``protobuf`` (compact, the
    high-rate topics of :mod:`sim.log_proto`) or ``json`` (every cosim topic in JSON, as logs
    before the compact encoding)."""

    rate_hz: Annotated[float, Field(gt=0.0, le=1000.0)] = 10.0
    encoding: Literal["protobuf", "json"] = "protobuf"


class Scenario(_Strict):
    """A validated scenario. ``seed`` fixes every random draw of the run. ``stop_when_complete``:
    the run ends once every vehicle's mission is complete (true), runs its whole ``duration``
    (false), or ends once the missions of the vehicles named in a list are complete (the others'
    are not waited for)."""

    schema_version: Literal[1] = SCHEMA_VERSION
    name: Annotated[str, Field(pattern=NAME_PATTERN, max_length=128)]
    description: str = ""
    seed: Annotated[int, Field(ge=0, lt=2**63)]
    duration: Annotated[float, quantity("time", 0.0, 30 * 86400.0, lo_open=True)]
    start_time: datetime = datetime(2026, 6, 21, 6, 0, tzinfo=UTC)
    stop_when_complete: bool | Annotated[list[str], Field(min_length=1)] = True
    origin: Origin
    logging: Logging = Logging()
    mavlink: Mavlink = Mavlink()
    metrics: Metrics = Metrics()
    wind: Wind = Wind()
    surveillance: Surveillance = Surveillance()
    weather: Weather | None = None
    object: list[TrafficObject] = []
    obstacle: list[Obstacle] = []
    geofence: list[GeofenceSpec] = []
    fault: list[Fault] = []
    utm: Utm | None = None
    vehicle: Annotated[list[VehicleSpec], Field(min_length=1)]

    @field_validator("start_time")
    @classmethod
    def _utc(cls, v: datetime) -> datetime:
        if v.tzinfo is None:
            raise ValueError("start_time needs a time zone, e.g. 2026-06-21T06:00:00Z")
        return v.astimezone(UTC)

    @model_validator(mode="after")
    def _loggable_time(self) -> Scenario:
        end = self.start_time + timedelta(seconds=self.duration)
        if not (self.start_time >= LOG_TIME_MIN and end < LOG_TIME_MAX):
            raise ValueError(
                f"start_time: the run ({self.start_time:%Y-%m-%dT%H:%M:%SZ} + duration) must lie between "
                f"{LOG_TIME_MIN:%Y-%m-%d} and {LOG_TIME_MAX:%Y-%m-%d} (MCAP log times since the Unix epoch)"
            )
        return self

    @model_validator(mode="after")
    def _references(self) -> Scenario:
        names = [v.name for v in self.vehicle]
        _require_unique(names, "vehicle names must be unique")
        for k, name in enumerate(self.stop_when_complete if isinstance(self.stop_when_complete, list) else []):
            if name not in names:
                raise ValueError(f"stop_when_complete[{k}]: no vehicle {name!r} (vehicles: {', '.join(names)})")
        for k, f in enumerate(self.fault):
            if f.vehicle not in names:
                raise ValueError(f"fault[{k}].vehicle: no vehicle {f.vehicle!r} (vehicles: {', '.join(names)})")
        for k, v in enumerate(self.vehicle):
            for link in ("utm_link", "peer_link"):
                if getattr(v, link) is not None and self.utm is None:
                    raise ValueError(f"vehicle[{k}].{link} needs the [utm] section (the authority)")
        targets: list[tuple[str, list[str]]] = []
        if self.utm is not None:
            targets = [
                ("spoof", [x.vehicle for x in self.utm.spoof]),
                ("mandate", [x.vehicle for x in self.utm.mandate]),
            ]
        for what, vehicles in targets:
            for k, name in enumerate(vehicles):
                if name not in names:
                    raise ValueError(f"utm.{what}[{k}].vehicle: no vehicle {name!r} (vehicles: {', '.join(names)})")
        ids = [m.id for m in self.utm.mandate] if self.utm is not None else []
        _require_unique(ids, "utm.mandate ids must be unique")
        if self.utm is not None and self.utm.weather and self.weather is None:
            raise ValueError("utm.weather needs the [weather] section (the weather service)")
        if self.utm is not None and self.utm.frame < 1.0 / self.logging.rate_hz - 1e-9:
            raise ValueError(
                f"utm.frame: {self.utm.frame:g} s is shorter than a log tick ({1.0 / self.logging.rate_hz:g} s), "
                "the authority's tick"
            )
        traffic = names + [o.id for o in self.object]
        _require_unique(traffic, "object ids must differ from each other and from vehicle names")
        ids = [o.id for o in self.obstacle] + [g.id for g in self.geofence]
        _require_unique(ids, "obstacle/geofence ids must be unique")
        if self.weather is not None and self.weather.nowcast_files:
            from sim.nowcast_files import NowcastError, load_series

            try:
                load_series(self.weather.nowcast_files, self.origin_point)
            except NowcastError as exc:
                raise ValueError(f"weather.nowcast_files: {exc}") from None
        return self

    @model_validator(mode="after")
    def _above_ground(self) -> Scenario:
        ground = self.origin.altitude
        for k, o in enumerate(self.obstacle):
            if o.base is None and o.top <= ground:
                raise ValueError(
                    f"obstacle[{k}].top: {o.top:g} m is not above the ground ({ground:g} m, origin altitude)"
                )
        for k, v in enumerate(self.vehicle):
            if not v.initial.on_ground and v.initial.altitude < ground:
                raise ValueError(
                    f"vehicle[{k}].initial.altitude: {v.initial.altitude:g} m is below the ground "
                    f"({ground:g} m, origin altitude)"
                )
            for j, w in enumerate(v.mission.waypoints):
                if w.altitude < ground:
                    raise ValueError(
                        f"vehicle[{k}].mission.waypoints[{j}].altitude: {w.altitude:g} m is below the ground "
                        f"({ground:g} m, origin altitude)"
                    )
        return self

    @model_validator(mode="after")
    def _within_envelope(self) -> Scenario:
        for k, v in enumerate(self.vehicle):
            af = get_airframe(v.aircraft)
            if not v.initial.on_ground and v.initial.altitude > af.ceiling_m:
                raise ValueError(
                    f"vehicle[{k}].initial.altitude: {v.initial.altitude:g} m is above the {af.name} ceiling "
                    f"({af.ceiling_m:g} m MSL)"
                )
            for j, w in enumerate(v.mission.waypoints):
                if w.altitude > af.ceiling_m:
                    raise ValueError(
                        f"vehicle[{k}].mission.waypoints[{j}].altitude: {w.altitude:g} m is above the {af.name} "
                        f"ceiling ({af.ceiling_m:g} m MSL)"
                    )
            if af.eas_envelope_mps is not None:
                _cruise_in_envelope(k, v, af.name, af.eas_envelope_mps)
        return self

    @property
    def origin_point(self) -> GeoPoint:
        """The origin as a WGS84 point in degrees (the local NED frame's origin)."""
        o = self.origin
        return GeoPoint(math.degrees(o.lat), math.degrees(o.lon), o.altitude)

    @property
    def epoch_ns(self) -> int:
        """Log time of sim time 0 [ns since the Unix epoch]."""
        return int(self.start_time.timestamp()) * 1_000_000_000


def _cruise_in_envelope(k: int, v: VehicleSpec, airframe: str, envelope: tuple[float, float]) -> None:
    """ValueError unless the cruise speed (TAS) is inside the EAS ``envelope`` [m/s] at every
    waypoint's altitude (ISA: EAS = TAS sqrt(rho / rho0))."""
    lo, hi = envelope
    tas = v.mission.cruise_speed
    for j, w in enumerate(v.mission.waypoints):
        ratio = math.sqrt(isa.RHO0 / isa.density_at_altitude(w.altitude))  # TAS per EAS
        eas = tas / ratio
        if not lo <= eas <= hi:
            raise ValueError(
                f"vehicle[{k}].mission.cruise_speed: {tas:g} m/s TAS is EAS {eas:.2f} m/s at waypoints[{j}] "
                f"({w.altitude:g} m), outside the {airframe} envelope EAS {lo:g}-{hi:g} m/s "
                f"(TAS {lo * ratio:.1f}-{hi * ratio:.1f} m/s there)"
            )


def _field_path(loc: tuple) -> str:
    out = ""
    for prev, part in zip((None, *loc), loc, strict=False):
        if prev == "planner" and part in PLANNERS:  # the planner type's tag in its union
            continue
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            shown = part if part and part.isprintable() and not any(c.isspace() for c in part) else repr(part)
            out += ("." if out else "") + shown
    return out or "(top level)"


def describe_error(err: ErrorDetails) -> str:
    """One line for a pydantic error: the field path and what is wrong."""
    path = _field_path(err["loc"])
    kind = err["type"]
    if kind == "extra_forbidden":
        return f"{path}: unknown key"
    if kind == "missing":
        return f"{path}: missing required field"
    if kind == "union_tag_invalid":
        field, ctx = err["ctx"]["discriminator"].strip("'"), err["ctx"]
        return f"{path}.{field}: unknown {field} {ctx['tag']!r} (known: {ctx['expected_tags']})"
    msg = err["msg"]
    for prefix in ("Value error, ", "Assertion failed, "):
        msg = msg.removeprefix(prefix)
    if kind == "string_pattern_mismatch" and err["ctx"]["pattern"] == NAME_PATTERN:
        msg = f"{err['input']!r} is not a name (no path separator, control character or leading dot)"
    if kind in ("greater_than_equal", "less_than_equal", "greater_than", "less_than"):
        msg = f"out of range: {msg.lower()} (got {err.get('input')!r})"
    return f"{path}: {msg}" if err["loc"] else msg  # whole-scenario checks name their fields


def parse_scenario(data: dict, source: str = "<scenario>") -> Scenario:
    """Validate a scenario mapping; ScenarioError names ``source`` and the first bad field.
    Files the scenario names are relative to ``source``'s folder (when it is a file)."""
    base = Path(source).parent if Path(source).is_file() else Path.cwd()
    try:
        return Scenario.model_validate(data, context={"base_dir": str(base)})
    except ValidationError as exc:
        errors = exc.errors(include_url=False)
        more = f" (+{len(errors) - 1} more)" if len(errors) > 1 else ""
        raise ScenarioError(f"{source}: {describe_error(errors[0])}{more}") from None


def load_scenario(path: str | Path) -> tuple[Scenario, str]:
    """Read and validate a TOML scenario; returns it with the file's text (kept in the log)."""
    path = Path(path)
    text = read_text(path, ScenarioError, "scenario")
    return parse_scenario(parse_toml(text, str(path), ScenarioError), str(path)), text
