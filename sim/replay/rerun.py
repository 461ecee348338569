"""Re-run a planner open-loop on a recorded run and compare its decisions with the recorded ones.

Every planner call of the run logged the planner's complete inputs: ``/<v>/plan/input`` (the
estimate, the mission progress, whether the call made a new plan) and ``/<v>/threats`` (every
sensed threat field, one message per call); map obstacles and geofences and the planner's
options come from the attached scenario. The planner (the scenario's own, or another kind or
parameter set) is called at every logged call with those inputs, in order, so its internal
state (replan timers, committed plans, nowcast caches) evolves as in the run; where the run
built its planner anew for a new mission (ground-station mode change, mission upload, repeated
mission), so does the re-run, from the mission logged with that call. Plans compare
vertex by vertex (positions [m], due times [s], labels and status), and a call that made a new
plan in one run but kept the previous plan in the other is a difference. Under a UTM authority
a rules planner joins it again and gets every directive (``/utm/directive``) at the time it
received it in the run.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import cast

import numpy as np

from aircraft.registry import get_airframe
from avoidance.rules.planner import RulesAvoider
from avoidance.utm.collision_case import CollisionCase
from avoidance.utm.directives import Directive
from avoidance.utm.weather_case import WeatherCase
from sim.core.mission import Mission
from sim.core.plan import Plan, Planner
from sim.core.threats import StormSnapshot
from sim.environment import geofence, obstacle_prism
from sim.mcap_read import LogReadError, read_attached_scenario
from sim.replay.runlog import RunLog
from sim.scenario import Utm
from sim.vehicle_log import (
    mission_from_setup,
    restore_progress,
    state_from_dict,
    storms_from_dicts,
    threats_from_dict,
)

PlannerFactory = Callable[[Mission], Planner]


@dataclass
class RerunReport:
    vehicle: str
    planner: str
    plans: int = 0
    same: int = 0
    max_position_diff_m: float = 0.0
    max_time_diff_s: float = 0.0
    first_difference_t: float | None = None
    differences: list[str] = field(default_factory=list)  # a line per differing plan (first 20)


def rerun_planner(path, vehicle: str, factory: PlannerFactory | None = None) -> RerunReport:
    """Re-run ``vehicle``'s planner (``factory(mission)``; default: the scenario's own, built as
    the run built it) on the log at ``path``. Calls made by a ground-station mode planner (HOLD,
    GUIDED) are not re-run; where the run built its planner anew (back to AUTO, a mission
    upload, a repeated mission: the call's logged ``mission_setup``), the re-run builds a new
    one for the logged mission too, so its state restarts as in the run."""
    from sim.vehicle_setup import mission_from_config, scenario_planner  # the runner's own construction

    log = RunLog(path)
    scenario = read_attached_scenario(path)
    if scenario is None:
        raise LogReadError(f"{path}: the scenario is not attached; cannot rebuild the planner")
    cfg = next((v for v in scenario.vehicle if v.name == vehicle), None)
    if cfg is None:
        raise LogReadError(f"{path}: no vehicle {vehicle!r} in the attached scenario")
    if not log.has(f"/{vehicle}/plan/input"):
        raise LogReadError(f"{path}: no /{vehicle}/plan/input (a log older than the planner-input records)")
    af = get_airframe(cfg.aircraft)
    gains = af.make_controller(cfg.gains).gains

    def build(mission: Mission) -> Planner:
        if factory:
            return factory(mission)
        return scenario_planner(cfg, mission, af, gains, scenario.wind, scenario.origin_point.alt_m)

    mission = mission_from_config(cfg, scenario.origin_point)
    planner = build(mission)
    alt0 = scenario.origin_point.alt_m
    obstacles = [obstacle_prism(c, alt0) for c in scenario.obstacle]
    fences = [geofence(c, alt0) for c in scenario.geofence]
    inputs, threats = log.topic(f"/{vehicle}/plan/input"), log.topic(f"/{vehicle}/threats")
    plans = iter(log.topic(f"/{vehicle}/plan").messages)
    if len(inputs) != len(threats):
        raise LogReadError(f"{path}: {len(inputs)} planner inputs but {len(threats)} threat records for {vehicle}")
    report = RerunReport(vehicle, getattr(planner, "name", type(planner).__name__))
    scenario_planner_name = inputs.messages[0]["planner"] if len(inputs) else ""
    logged_storms: list[dict] | None = None
    storms: list[StormSnapshot] = []
    directives = _directives(log, vehicle, planner, scenario.utm)
    called = False  # the scenario's planner has been called: a logged mission_setup rebuilds it
    for rec_in, rec_th in zip(inputs.messages, threats.messages, strict=True):
        recorded = next(plans) if rec_in["new_plan"] else None
        if rec_in["planner"] != scenario_planner_name:  # a ground-station mode planner flew this call
            continue
        if "mission_setup" in rec_in and called:  # the run built its planner anew before this call
            mission = mission_from_setup(rec_in["mission_setup"])
            planner = build(mission)
        called = True
        if rec_th["storms"] != logged_storms:  # a new nowcast: new snapshot objects, as in the run
            logged_storms, storms = rec_th["storms"], storms_from_dicts(rec_th["storms"])
        restore_progress(mission, rec_in["mission"])
        t = float(rec_in["t"])
        while directives and directives[0][0] <= t + 1e-9:  # handed over before the planner ran
            received, d = directives.pop(0)
            cast(RulesAvoider, planner).receive_directive(d, received)
        new = planner.plan(state_from_dict(rec_in["estimate"]), threats_from_dict(rec_th, obstacles, fences, storms), t)
        _compare(report, t, recorded, new if new.t == t else None)
    return report


def _directives(log: RunLog, vehicle: str, planner: object, utm: Utm | None) -> list[tuple[float, Directive]]:
    """The UTM directives ``vehicle`` received, in order (empty without an authority or for a
    planner that does not obey one); the planner joins the authority as in the run."""
    if utm is None or not isinstance(planner, RulesAvoider):
        return []
    planner.join_utm(vehicle, utm.lost_after)
    recs = [m for m in log.topic("/utm/directive").messages if m["to"] == vehicle and m["received_t"] is not None]
    return [
        (
            float(m["received_t"]),
            Directive(
                m["frame"],
                m["t"],
                vehicle,
                tuple(CollisionCase.from_record(c) for c in m["cases"]),
                tuple(WeatherCase.from_record(w) for w in m.get("weather", [])),
            ),
        )
        for m in sorted(recs, key=lambda m: (m["received_t"], m["frame"]))
    ]


def _compare(report: RerunReport, t: float, rec: dict | None, new: Plan | None) -> None:
    """One planner call: ``rec`` the recorded new plan, ``new`` the re-run's (None: the call kept
    the previous plan)."""
    if rec is None and new is None:
        return
    report.plans += 1
    why = _differences(report, rec, new)
    if not why:
        report.same += 1
        return
    if report.first_difference_t is None:
        report.first_difference_t = t
    if len(report.differences) < 20:
        report.differences.append(f"t={t:.2f} s: " + "; ".join(why))


def _differences(report: RerunReport, rec: dict | None, new: Plan | None) -> list[str]:
    """How the re-run's plan differs from the recorded one; updates the report's largest
    vertex differences."""
    if rec is None:
        return ["the recorded run kept its plan, the re-run made a new one"]
    if new is None:
        return ["the re-run kept its plan, the recorded run made a new one"]
    why = []
    if rec["status"] != new.status.value:
        why.append(f"status {rec['status']} -> {new.status.value}")
    old_p = np.asarray(rec["positions"], float)
    if old_p.shape != new.positions.shape or rec["labels"] != new.labels.tolist():
        return [*why, f"{len(old_p)} -> {len(new.positions)} vertices"]
    dp = float(np.max(np.linalg.norm(old_p - new.positions, axis=1)))
    dt = float(np.max(np.abs(np.asarray(rec["times"], float) - new.times)))
    report.max_position_diff_m = max(report.max_position_diff_m, dp)
    report.max_time_diff_s = max(report.max_time_diff_s, dt)
    if dp > 1e-6 or dt > 1e-6:
        why.append(f"vertices differ by up to {dp:.3g} m / {dt:.3g} s")
    return why
