"""Re-run a planner open-loop on a recorded run and compare its decisions with the recorded ones.

For every plan a vehicle logged, the planner (the scenario's own, or another kind or parameter
set) is fed what the recorded one saw: the logged estimate at that time, the logged threats,
and the mission progress up to that time (waypoints reached before it, from the events). Plans
compare vertex by vertex: positions [m], due times [s], labels and status.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from shapely.geometry import Polygon

from aircraft.registry import get_airframe
from sim.core.mission import Mission
from sim.core.plan import Planner, Threats
from sim.core.threats import IntruderTrack, SphereThreat, StormSnapshot
from sim.mcap_read import LogReadError, read_attached_scenario
from sim.planner_registry import make_planner
from sim.replay.runlog import RunLog
from sim.vehicle_log import state_from_dict

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


def _threats(d: dict) -> Threats:
    a = np.asarray
    return Threats(
        intruders=[
            IntruderTrack(
                i["id"],
                i["t"],
                a(i["pos_ned"]),
                a(i["vel_ned"]),
                i["radius_m"],
                a(i["pos_cov"]),
                a(i["vel_cov"]),
                i["cooperative"],
            )
            for i in d["intruders"]
        ],
        spheres=[
            SphereThreat(s["id"], s["t"], a(s["center_ned"]), s["radius_m"], a(s["vel_ned"]), a(s["center_cov"]))
            for s in d["spheres"]
        ],
        storms=[StormSnapshot(s["t"], tuple(Polygon(c) for c in s["cells"])) for s in d["storms"]],
    )


def rerun_planner(path, vehicle: str, factory: PlannerFactory | None = None) -> RerunReport:
    """Re-run ``vehicle``'s planner (``factory(mission)``; default: the scenario's own kind) on
    the log at ``path``."""
    from sim.vehicle_setup import mission_from_config  # the runner's own mission construction

    log = RunLog(path)
    scenario = read_attached_scenario(path)
    if scenario is None:
        raise LogReadError(f"{path}: the scenario is not attached; cannot rebuild the planner")
    cfg = next((v for v in scenario.vehicle if v.name == vehicle), None)
    if cfg is None:
        raise LogReadError(f"{path}: no vehicle {vehicle!r} in the attached scenario")
    mission = mission_from_config(cfg, scenario.origin_point)
    kind = get_airframe(cfg.aircraft).kind
    planner = (
        factory(mission)
        if factory
        else make_planner(
            cfg.planner.type, mission, kind, cfg.planner.options, wind_ne_mps=(scenario.wind.north, scenario.wind.east)
        )
    )
    est = log.topic(f"/{vehicle}/est/state")
    threats = log.topic(f"/{vehicle}/threats")
    plans = log.topic(f"/{vehicle}/plan")
    prefix = f"{vehicle}: waypoint "
    reached = sorted(
        (t, int(text[len(prefix) :].split("/")[0]) - 1)
        for t, text in log.events()
        if text.startswith(prefix) and text.endswith(" reached")
    )
    report = RerunReport(vehicle, getattr(planner, "name", type(planner).__name__))
    for t, rec in zip(plans.t, plans.messages, strict=False):
        for tr, k in reached:
            if tr < t:  # at a tick the planner runs before the control that marks a waypoint
                mission.mark_reached(k, tr)
        i = int(np.searchsorted(est.t, t, side="right")) - 1
        j = int(np.searchsorted(threats.t, t, side="right")) - 1
        if i < 0 or j < 0:
            raise LogReadError(f"{path}: no estimate or threats logged before the plan at t={t:.2f} s")
        new = planner.plan(state_from_dict(est.messages[i]), _threats(threats.messages[j]), float(t))
        _compare(report, float(t), rec, new)
    return report


def _compare(report: RerunReport, t: float, rec: dict, new) -> None:
    report.plans += 1
    old_p, old_t = np.asarray(rec["positions"]), np.asarray(rec["times"])
    why = []
    if rec["status"] != new.status.value:
        why.append(f"status {rec['status']} -> {new.status.value}")
    if old_p.shape != new.positions.shape or rec["labels"] != new.labels.tolist():
        why.append(f"{len(old_p)} -> {len(new.positions)} vertices")
    else:
        dp = float(np.max(np.linalg.norm(old_p - new.positions, axis=1)))
        dt = float(np.max(np.abs(old_t - new.times)))
        report.max_position_diff_m = max(report.max_position_diff_m, dp)
        report.max_time_diff_s = max(report.max_time_diff_s, dt)
        if dp > 1e-6 or dt > 1e-6:
            why.append(f"vertices differ by up to {dp:.3g} m / {dt:.3g} s")
    if why:
        if report.first_difference_t is None:
            report.first_difference_t = t
        if len(report.differences) < 20:
            report.differences.append(f"t={t:.2f} s: " + "; ".join(why))
    else:
        report.same += 1
