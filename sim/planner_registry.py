"""Build a vehicle's planner from its scenario configuration (one place for the runner and for
re-running planners on a log).

``options`` are fields of the planner's own configuration dataclass, in its units (SI):
geometric ``GeometricConfig``, MPTP ``MptpConfig``; the reach-set planner takes ``period`` (its
movement period [s]), ``constraint_margin`` (safety-margin ring of constraints [m]), ``constraint_mode``
(polygon / circle), ``intruder_margin`` (added to
intruders' body radius [m]), ``separations``
(ACAS-like reach sets, e.g. ["horizontal"]), ``rules`` (the enabled rules of
the air of a cooperative UAS, a list of codes) and ``rules_<field>`` (the other fields of
``avoidance.rules.config.RulesConfig``); pursuit takes ``target`` (the pursued vehicle, S14);
follow_mission takes none. Unknown options are an error naming them.
"""

from __future__ import annotations

import dataclasses
import importlib

import numpy as np

from avoidance.follow_mission import FollowMissionPlanner
from avoidance.rules.config import RULES_FIELDS, RulesConfig
from sim.core.mission import Mission
from sim.core.plan import Planner

# planner -> (airframe kinds it flies, its config dataclass "module:Class" or the option names)
_PLANNERS: dict[str, tuple[tuple[str, ...], str | tuple[str, ...]]] = {
    "follow_mission": (("fixed_wing", "multirotor"), ()),
    "geometric": (("multirotor",), "avoidance.geometric.config:GeometricConfig"),
    "reachset": (
        ("fixed_wing", "multirotor"),
        (
            "period",
            "constraint_margin",
            "constraint_mode",
            "intruder_margin",
            "separations",
            "rules",
            *(f"rules_{f}" for f in RULES_FIELDS),
        ),
    ),
    "mptp": (("fixed_wing",), "guidance.mptp.config:MptpConfig"),
    "pursuit": (("multirotor",), ("target",)),
}


class PlannerConfigError(ValueError):
    """A planner is unknown, does not fit the airframe, or an option is unknown or invalid."""


def _class(ref: str):
    module, _, name = ref.partition(":")
    return getattr(importlib.import_module(module), name)


def check_planner(kind: str, airframe_kind: str, options: dict) -> None:
    """Cheap check of a planner choice (no planner is built); PlannerConfigError otherwise."""
    if kind not in _PLANNERS:
        raise PlannerConfigError(f"unknown planner {kind!r} (known: {', '.join(_PLANNERS)})")
    kinds, conf = _PLANNERS[kind]
    if airframe_kind not in kinds:
        raise PlannerConfigError(f"{kind} planner does not fly a {airframe_kind} (it flies: {', '.join(kinds)})")
    names = {f.name for f in dataclasses.fields(_class(conf))} if isinstance(conf, str) else set(conf)
    unknown = sorted(set(options) - names)
    if unknown:
        raise PlannerConfigError(
            f"{kind} planner: unknown option(s) {', '.join(unknown)}"
            + (f" (known: {', '.join(sorted(names))})" if names else " (it takes none)")
        )
    if isinstance(conf, str):  # values too (the config dataclass validates them)
        _config(kind, options)
    if kind == "reachset":
        _reachset_config(options)
        if "rules" in options:
            _rules_config(options)
    if kind == "pursuit" and not isinstance(options.get("target"), str):
        raise PlannerConfigError("pursuit planner: option target (the pursued vehicle's name) is required")


def _config(kind: str, options: dict, **fixed):
    try:
        return _class(_PLANNERS[kind][1])(**{**fixed, **options})
    except (TypeError, ValueError) as exc:
        raise PlannerConfigError(f"{kind} planner: {exc}") from None


def _reachset_config(options: dict):
    """``constraint_margin`` [m]; ``constraint_mode`` (``polygon`` exact, ``circle`` the thesis'
    Welzl barrel); ``intruder_margin`` [m] added to every intruder's body radius;
    ``separations``: planar separations of ACAS-like reach sets
    (spec §4.8, e.g. ["horizontal"], the thesis' S1-S4) used in both modes instead of the 3-D
    harmonic / combined sets."""
    from avoidance.reachset.config import AvoidanceConfig, ConstraintConfig, ExpansionConfig, ReachSetConfig
    from avoidance.reachset.expansion import SEPARATIONS

    cfg = AvoidanceConfig()
    if "constraint_margin" in options:
        margin = options["constraint_margin"]
        if isinstance(margin, bool) or not isinstance(margin, (int, float)) or margin < 0:
            raise PlannerConfigError(
                f"reachset planner: constraint_margin must be a number of metres >= 0 (got {margin!r})"
            )
        cfg = dataclasses.replace(cfg, constraints=ConstraintConfig(safety_margin=float(margin)))
    if "constraint_mode" in options:
        mode = options["constraint_mode"]
        if mode not in ("polygon", "circle"):
            raise PlannerConfigError(f"reachset planner: constraint_mode must be polygon or circle (got {mode!r})")
        cfg = dataclasses.replace(cfg, constraints=dataclasses.replace(cfg.constraints, mode=mode))
    if "intruder_margin" in options:
        margin = options["intruder_margin"]
        if isinstance(margin, bool) or not isinstance(margin, (int, float)) or margin < 0:
            raise PlannerConfigError(
                f"reachset planner: intruder_margin must be a number of metres >= 0 (got {margin!r})"
            )
        cfg = dataclasses.replace(cfg, intruders=dataclasses.replace(cfg.intruders, body_margin=float(margin)))
    if "separations" in options:
        seps = options["separations"]
        if not isinstance(seps, list) or not seps or any(s not in SEPARATIONS for s in seps):
            raise PlannerConfigError(
                f"reachset planner: separations must be a non-empty list of {', '.join(SEPARATIONS)} (got {seps!r})"
            )
        acas = ReachSetConfig.single(ExpansionConfig.acas(tuple(seps)))
        cfg = dataclasses.replace(cfg, navigation=acas, avoidance=acas)
    return cfg


def _reachset_automaton(airframe_kind: str, cruise: float, options: dict, bank_limit_rad: float = np.radians(20.0)):
    from avoidance.reachset.movement import haps_automaton, multirotor_automaton

    period = float(options.get("period", 1.0))
    return (
        multirotor_automaton(cruise, period)
        if airframe_kind == "multirotor"
        else haps_automaton(cruise, period, bank_limit_rad)
    )


def reachset_grid_range(airframe_kind: str, cruise: float, options: dict) -> float:
    """Range [m] of the reach-set avoidance grid flown at ``cruise`` [m/s]: layers x the movement
    length of the active segment (a sensor that must see the grid needs at least this)."""
    from avoidance.reachset.movement import KinState

    sma = _reachset_automaton(airframe_kind, cruise, options)
    length = sma.active(KinState(np.zeros(3), np.zeros(3), 0.0, cruise)).table.config.length
    return float(_reachset_config(options).grid.scaled(length).d_range[1])


def _rules_config(options: dict):
    """The rules of the air of a reach-set planner: ``rules`` (enabled codes) + ``rules_<field>``."""
    table = {k.removeprefix("rules_"): v for k, v in options.items() if k.startswith("rules_")}
    try:
        return RulesConfig.from_options({"enabled": options["rules"], **table})
    except (TypeError, ValueError) as exc:
        raise PlannerConfigError(f"reachset planner: {exc}") from None


def make_planner(
    kind: str,
    mission: Mission,
    airframe_kind: str = "multirotor",
    options: dict | None = None,
    bank_limit_rad: float = np.radians(20.0),
) -> Planner:
    """The planner called ``kind`` for ``mission`` flown by an ``airframe_kind`` vehicle."""
    options = dict(options or {})
    check_planner(kind, airframe_kind, options)
    if kind == "follow_mission":
        return FollowMissionPlanner(mission)
    if kind == "pursuit":
        from avoidance.pursuit import PursuitPlanner

        return PursuitPlanner(mission, options["target"])
    if kind == "geometric":
        from avoidance.geometric.planner import GeometricAvoider

        start = mission.start if mission.start is not None else mission.waypoints[0]
        return GeometricAvoider(
            np.vstack([start, mission.waypoints]), mission.cruise_speed, _config(kind, options), first_label=-1
        )
    if kind == "reachset":
        from avoidance.reachset.planner import ReachSetAvoider

        sma = _reachset_automaton(airframe_kind, mission.cruise_speed, options, bank_limit_rad)
        if "rules" not in options:
            return ReachSetAvoider(mission, sma, _reachset_config(options))
        from avoidance.rules.planner import RulesAvoider

        return RulesAvoider(mission, sma, _rules_config(options), _reachset_config(options))
    from guidance.mptp.planner import MptpPlanner

    return MptpPlanner(mission, _config(kind, options, tas_mps=mission.cruise_speed, bank_max=bank_limit_rad))
