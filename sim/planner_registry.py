"""The planner registry: every planner type with its typed options, its factory and its own log
records. The engine knows planners only through this table; adding a planner is one package plus
one :data:`PLANNERS` entry (the scenario validator takes the options model from here, so a bad
option is a field-named error like any other).

Options are the fields of the planner's own options model, in SI units: the geometric avoider
``avoidance.geometric.config.GeometricConfig``, the MPTP ``guidance.mptp.config.MptpConfig``
(``tas_mps`` and ``bank_max`` default to the mission's cruise speed and the airframe's bank
limit, ``start_lead_s`` for the fly-over turn models to the follower's turn lead), the
reach-set planner ``avoidance.rules.options.RulesOptions`` (reach-set options plus the rules of
the air), pursuit ``target``; follow_mission takes none.
"""

from __future__ import annotations

import dataclasses
import typing
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, create_model, model_validator
from pydantic.errors import PydanticSchemaGenerationError

from avoidance.geometric.config import GeometricConfig
from avoidance.rules.options import RulesOptions
from guidance.mptp.config import MptpConfig
from sim.core.mission import Mission
from sim.core.plan import Plan, Planner
from sim.planner_records import RecordSink, geometric_records, mptp_records, reachset_records


@dataclass(frozen=True, slots=True)
class BuildContext:
    """What a planner is built for: the mission (NED [m]), the airframe kind
    (``fixed_wing``/``multirotor``), its bank limit [rad] and its controller's bank-command slew
    rate (``roll_rate_rad_s`` [rad/s]; None: none known), how far ahead [s] its plan follower
    feeds a planned turn forward (``turn_lead_s``, the fixed-wing ``l1_turn_lead_s``) and the
    scenario's steady wind (north, east) [m/s] (the MPTP's forecast); ``wind_profile``: when the
    scenario's wind varies with altitude or time, its profile as rows (t [s], up [m] above the
    origin, north, east [m/s]; ``sim.wind_field.WindField.forecast_rows``), the MPTP's forecast
    instead of the steady wind."""

    mission: Mission
    airframe_kind: str
    bank_limit_rad: float = float(np.radians(20.0))
    wind_ne_mps: tuple[float, float] = (0.0, 0.0)
    wind_profile: tuple[tuple[float, float, float, float], ...] = ()
    turn_lead_s: float = 0.0
    roll_rate_rad_s: float | None = None


@dataclass(frozen=True, slots=True)
class PlannerType:
    """One planner type: the airframe kinds it flies, its options model, its factory, its own
    log records (beside the common ``/<v>/plan``) and, for planners that need a sensor to see
    their grid, the range [m] they need (``sensing_range(options, airframe_kind, cruise)``); for
    planners that rate only nearby traffic, ``awareness(planner)``: the (range [m], horizon [s])
    within which a built planner needs traffic sensed (``sim/broad_phase.py``; ``None``, or no
    function: every track)."""

    name: str
    airframes: tuple[str, ...]
    options: type[BaseModel]
    build: Callable[[Any, BuildContext], Planner]
    records: Callable[[RecordSink, Any, Plan, float], None] | None = None
    sensing_range: Callable[[Any, str, float], float] | None = None
    awareness: Callable[[Any], tuple[float, float] | None] | None = None


class PlannerConfigError(ValueError):
    """A planner is unknown or does not fit the airframe."""


class DataclassOptions(BaseModel):
    """Options model of a planner configured by a frozen dataclass (``config_class``): its fields,
    types and defaults; validating the options also builds the dataclass, so that the dataclass's
    own checks surface as the options' error."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    config_class: ClassVar[type]

    def config(self, **fixed: Any) -> Any:
        """The configuration: ``fixed`` values, overridden by the options the scenario gives."""
        return self.config_class(**{**fixed, **{k: getattr(self, k) for k in self.model_fields_set}})

    @model_validator(mode="after")
    def _buildable(self) -> DataclassOptions:
        self.config()
        return self


def _field_type(hint: Any) -> Any:
    """``hint`` where pydantic can validate it; ``Any`` for a type it cannot (e.g. a shapely
    polygon given as a vertex list, which the dataclass converts itself)."""
    try:
        TypeAdapter(hint)
    except PydanticSchemaGenerationError:
        return Any
    return hint


def dataclass_options(config: type) -> type[DataclassOptions]:
    """The options model of the frozen dataclass ``config``."""
    hints = typing.get_type_hints(config)
    fields: dict[str, Any] = {}
    for f in dataclasses.fields(config):
        if f.default_factory is not dataclasses.MISSING:
            default: Any = Field(default_factory=f.default_factory)
        else:
            default = f.default if f.default is not dataclasses.MISSING else ...
        fields[f.name] = (_field_type(hints[f.name]), default)
    model = create_model(f"{config.__name__}Options", __base__=DataclassOptions, **fields)
    model.config_class = config
    return model


class NoOptions(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class PursuitOptions(BaseModel):
    """``target``: the name of the pursued vehicle."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    target: str


def _follow_mission(options: NoOptions, ctx: BuildContext) -> Planner:
    from avoidance.follow_mission import FollowMissionPlanner

    return FollowMissionPlanner(ctx.mission)


def _pursuit(options: PursuitOptions, ctx: BuildContext) -> Planner:
    from avoidance.pursuit import PursuitPlanner

    return PursuitPlanner(ctx.mission, options.target)


def _geometric(options: DataclassOptions, ctx: BuildContext) -> Planner:
    from avoidance.geometric.planner import GeometricAvoider

    m = ctx.mission
    start = m.start if m.start is not None else m.waypoints[0]
    return GeometricAvoider(np.vstack([start, m.waypoints]), m.cruise_speed, options.config(), first_label=-1)


def _reachset(options: RulesOptions, ctx: BuildContext) -> Planner:
    from avoidance.reachset.planner import ReachSetAvoider
    from avoidance.rules.planner import RulesAvoider

    sma = options.automaton(ctx.airframe_kind, ctx.mission.cruise_speed, ctx.bank_limit_rad)
    rules = options.rules_config()
    turns_in_place = ctx.airframe_kind == "multirotor"
    if rules is None:
        return ReachSetAvoider(ctx.mission, sma, options.avoidance_config(), turns_in_place=turns_in_place)
    return RulesAvoider(ctx.mission, sma, rules, options.avoidance_config(), turns_in_place=turns_in_place)


def _mptp(options: DataclassOptions, ctx: BuildContext) -> Planner:
    """The MPTP; its wind forecast is the scenario's wind profile in height and time (or its
    steady wind) plus the option ``wind_error_ne_mps`` everywhere, or none with
    ``wind_forecast = "none"`` (still air) or ``"estimate"`` (the planner's own measure). Its
    fly-over turn models start each search the follower's turn lead ahead (``start_lead_s``,
    lead_in.py); the simple model's fly-by corners carry no turn rate to lead. Its simulated
    turns roll at the controller's bank slew rate when one is known (``roll_rate_max``; the
    option overrides it)."""
    from guidance.mptp.planner import MptpPlanner
    from guidance.mptp.wind import WindForecast

    lead = ctx.turn_lead_s if getattr(options, "turn_model", "simple") != "simple" else 0.0
    fixed = {"tas_mps": ctx.mission.cruise_speed, "bank_max": ctx.bank_limit_rad, "start_lead_s": lead}
    if ctx.roll_rate_rad_s is not None:
        fixed["roll_rate_max"] = ctx.roll_rate_rad_s
    cfg = options.config(**fixed)
    if cfg.wind_forecast != "scenario":  # still air, or the planner's own estimate
        return MptpPlanner(ctx.mission, cfg, wind=None)
    rows = np.array(ctx.wind_profile or [(0.0, 0.0, *ctx.wind_ne_mps)], float)
    times, ups = np.unique(rows[:, 0]), np.unique(rows[:, 1])
    ne = rows[:, 2:].reshape(len(times), len(ups), 2) + cfg.wind_error_ne_mps
    return MptpPlanner(ctx.mission, cfg, wind=WindForecast(ups, ne, times))


def _reachset_awareness(planner: Any) -> tuple[float, float] | None:
    """The plain reach-set avoider rates only traffic that can reach its grids; the rules of the
    air negotiate with every cooperative peer they hear, so they need every track."""
    from avoidance.rules.planner import RulesAvoider

    return None if isinstance(planner, RulesAvoider) else planner.awareness()


def _grid_range(options: RulesOptions, airframe_kind: str, cruise: float) -> float:
    return options.grid_range(airframe_kind, cruise)


_BOTH = ("fixed_wing", "multirotor")
PLANNERS: dict[str, PlannerType] = {
    p.name: p
    for p in (
        PlannerType("follow_mission", _BOTH, NoOptions, _follow_mission),
        PlannerType("geometric", ("multirotor",), dataclass_options(GeometricConfig), _geometric, geometric_records),
        PlannerType("reachset", _BOTH, RulesOptions, _reachset, reachset_records, _grid_range, _reachset_awareness),
        PlannerType("mptp", ("fixed_wing",), dataclass_options(MptpConfig), _mptp, mptp_records),
        PlannerType("pursuit", ("multirotor",), PursuitOptions, _pursuit),
    )
}


def planner_type(name: str) -> PlannerType:
    try:
        return PLANNERS[name]
    except KeyError:
        raise PlannerConfigError(f"unknown planner {name!r} (known: {', '.join(PLANNERS)})") from None


def planner_awareness(kind: str, planner: Planner) -> tuple[float, float] | None:
    """The (range [m], horizon [s]) within which the built ``planner`` of type ``kind`` needs
    traffic sensed; ``None``: every track."""
    entry = planner_type(kind)
    return None if entry.awareness is None else entry.awareness(planner)


def make_planner(
    kind: str,
    mission: Mission,
    airframe_kind: str = "multirotor",
    options: BaseModel | dict | None = None,
    bank_limit_rad: float = float(np.radians(20.0)),
    wind_ne_mps: tuple[float, float] = (0.0, 0.0),
    wind_profile: tuple[tuple[float, float, float, float], ...] = (),
    turn_lead_s: float = 0.0,
    roll_rate_rad_s: float | None = None,
) -> Planner:
    """The planner ``kind`` for ``mission`` flown by an ``airframe_kind`` vehicle; ``options`` is
    the type's options model (a mapping is validated into it); ``wind_ne_mps`` the scenario's
    steady wind (north, east) [m/s], ``wind_profile`` its profile, ``turn_lead_s`` [s]
    the follower's turn lead, ``roll_rate_rad_s`` [rad/s] the controller's bank slew rate (see
    BuildContext)."""
    entry = planner_type(kind)
    if airframe_kind not in entry.airframes:
        raise PlannerConfigError(
            f"{kind} planner does not fly a {airframe_kind} (it flies: {', '.join(entry.airframes)})"
        )
    if not isinstance(options, entry.options):
        options = entry.options.model_validate(options or {})
    return entry.build(
        options,
        BuildContext(mission, airframe_kind, bank_limit_rad, wind_ne_mps, wind_profile, turn_lead_s, roll_rate_rad_s),
    )
