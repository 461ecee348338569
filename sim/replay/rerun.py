"""Re-run a planner open-loop on a recorded run and compare its decisions with the recorded ones.

Every planner call of the run logged the planner's complete inputs: ``/<v>/plan/input`` (the
estimate, the mission progress, whether the call made a new plan) and ``/<v>/threats`` (every
sensed threat field, one message per call); map obstacles and geofences and the planner's
options come from the attached scenario. The planner (the scenario's own, or another kind or
parameter set) is called at every logged call with those inputs, in order, so its internal
state (replan timers, committed plans, nowcast caches) evolves as in the run; where the run
built its planner anew for a new mission (ground-station mode change, mission upload, repeated
mission), so does the re-run, from the mission logged with that call; the calls of a
ground-station mode planner (HOLD, GUIDED) are re-run by that planner, built again from what it
was built from. An observing planner (sim.core.plan.ObservingPlanner) gets the estimates it
observed between its calls (``/<v>/plan/observation``) at their times, before the calls at or
after them. Plans compare vertex by vertex (positions [m], due times [s], labels and
status), and a call that made a new plan in one run but kept the previous plan in the other is
a difference. Under a UTM authority a rules planner joins it again and gets every directive
(``/utm/directive``) and every message of its vehicle-to-vehicle link (``/utm/peer/*``) at the
time it received it in the run.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from aircraft.registry import get_airframe
from avoidance.rules.planner import RulesAvoider
from avoidance.utm.collision_case import CollisionCase
from avoidance.utm.directives import Directive
from avoidance.utm.mandate import Mandate
from avoidance.utm.response import PeerMessage
from avoidance.utm.weather_case import WeatherCase
from sim.core.mission import Mission
from sim.core.plan import ObservingPlanner, Plan, Planner, Threats
from sim.core.threats import StormSnapshot
from sim.environment import geofence, obstacle_prism
from sim.mcap_read import LogReadError, read_attached_scenario, read_info
from sim.position_planners import mode_planner
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
    mode_plans: int = 0  # of ``plans``: made by ground-station mode planners (HOLD, GUIDED)
    differences: list[str] = field(default_factory=list)  # a line per differing plan (first 20)


def rerun_planner(path, vehicle: str, factory: PlannerFactory | None = None) -> RerunReport:
    """Re-run ``vehicle``'s planner (``factory(mission)``; default: the scenario's own, built as
    the run built it) on the log at ``path``. Where the run built its planner anew (back to
    AUTO, a mission upload, a repeated mission: the call's logged ``mission_setup``), the re-run
    builds a new one for the logged mission too, so its state restarts as in the run. Calls of
    a ground-station mode planner (HOLD, GUIDED) are re-run by that mode planner, built from
    its logged ``mode_setup`` (logs older than that record skip them).

    Under a UTM authority the directives go to the planner flying when they were handed over,
    before the calls at that time (the authority runs before the planners in a tick): to none
    while a mode planner flies, and a rebuilt rules planner joins the authority with the first
    directive it gets (:meth:`sim.utm_authority.Member.obeying`)."""
    from sim.vehicle_setup import mission_from_config, scenario_planner  # the runner's own construction

    log = RunLog(path, _rerun_topics(path, vehicle))
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
    inbox = _Directives(log, vehicle, planner, scenario.utm, cfg.peer_link is not None)
    flying: Planner | None = planner  # the planner directives reach (None: a mode planner flies)
    mode: Planner | None = None  # the ground-station mode planner, rebuilt from its logged setup
    called = False  # the scenario's planner has been called: a logged mission_setup rebuilds it
    observed = _Observations(log, vehicle)
    for rec_in, rec_th in zip(inputs.messages, threats.messages, strict=True):
        recorded = next(plans) if rec_in["new_plan"] else None
        t = float(rec_in["t"])
        inbox.deliver(flying, t)
        observed.deliver(planner, t)
        if rec_in["planner"] != scenario_planner_name:  # a ground-station mode planner flew this call
            flying = None
            if "mission_setup" in rec_in:
                setup = rec_in.get("mode_setup")
                mode = None if setup is None else mode_planner(rec_in["planner"], setup)
            if mode is not None:
                before = report.plans
                new = mode.plan(state_from_dict(rec_in["estimate"]), Threats(), t)
                _compare(report, t, recorded, new if new.t == t else None)
                report.mode_plans += report.plans - before
            continue
        if "mission_setup" in rec_in and called:  # the run built its planner anew before this call
            mission = mission_from_setup(rec_in["mission_setup"])
            planner = build(mission)
        flying, called = planner, True
        if rec_th["storms"] != logged_storms:  # a new nowcast: new snapshot objects, as in the run
            logged_storms, storms = rec_th["storms"], storms_from_dicts(rec_th["storms"])
        restore_progress(mission, rec_in["mission"])
        new = planner.plan(state_from_dict(rec_in["estimate"]), threats_from_dict(rec_th, obstacles, fences, storms), t)
        _compare(report, t, recorded, new if new.t == t else None)
    return report


def _rerun_topics(path, vehicle: str) -> list[str]:
    """The topics a re-run reads (the planner's inputs, plans and directives), of those logged."""
    have = {ti.topic for ti in read_info(path).topics}
    want = [f"/{vehicle}/{s}" for s in ("plan/input", "plan/observation", "threats", "threats/lidar", "plan")]
    want += ["/utm/directive"]
    want += [f"/utm/peer/{k}" for k in PEER_KINDS]
    return [t for t in want if t in have]


PEER_KINDS = ("notification", "claim", "ack")


def _directive(m: dict, vehicle: str) -> Directive:
    """The directive of a ``/utm/directive`` record."""
    return Directive(
        m["frame"],
        m["t"],
        vehicle,
        tuple(CollisionCase.from_record(c) for c in m["cases"]),
        tuple(WeatherCase.from_record(w) for w in m.get("weather", [])),
        tuple(Mandate.from_record(x) for x in m.get("mandates", [])),
    )


def _peer_message(kind: str, m: dict) -> PeerMessage:
    """The message of a ``/utm/peer/<kind>`` record."""
    case = CollisionCase.from_record(m["case"]) if "case" in m else None
    pos, vel = (np.asarray(m[k], float) if k in m else None for k in ("pos_enu", "vel_enu"))
    return PeerMessage(kind, m["from"], m["to"], m["t"], case, pos, vel)


class _Observations:
    """The estimates ``vehicle``'s planner observed between its calls, in time order. The run
    logs only those its planner took, and a planner built anew observes from its first call on,
    so every one up to a call went to the planner flying before that call."""

    def __init__(self, log: RunLog, vehicle: str):
        topic = f"/{vehicle}/plan/observation"
        self.queue = deque(log.topic(topic).messages if log.has(topic) else [])

    def deliver(self, planner: Planner, t: float) -> None:
        """Hand ``planner`` the estimates observed by ``t`` [s] (dropped when it does not observe,
        a re-run by another kind of planner)."""
        while self.queue and float(self.queue[0]["t"]) <= t + 1e-9:
            m = self.queue.popleft()
            if isinstance(planner, ObservingPlanner):
                planner.observe(state_from_dict(m["estimate"]), float(m["t"]))


class _Directives:
    """The UTM directives and the vehicle-to-vehicle messages ``vehicle`` was handed, in
    order (directives first within a tick, as the authority ticks before the peer links), for
    the rules planner that flew (none without an authority or for a planner that does not obey
    one); the first planner joins the authority at the start, as in the run."""

    def __init__(self, log: RunLog, vehicle: str, planner: object, utm: Utm | None, peer_link: bool):
        self.vehicle, self.peer_link = vehicle, peer_link
        self.lost_after = 0.0 if utm is None else utm.lost_after
        self.joined: object | None = None
        self.queue: list[tuple[float, int, float, Directive | PeerMessage]] = []
        if utm is None or not isinstance(planner, RulesAvoider):
            return
        self._join(planner)
        for m in log.topic("/utm/directive").messages:
            if m["to"] == vehicle and m["received_t"] is not None:
                self.queue.append((float(m["received_t"]), 0, float(m["frame"]), _directive(m, vehicle)))
        for kind in PEER_KINDS:
            for m in log.topic(f"/utm/peer/{kind}").messages if log.has(f"/utm/peer/{kind}") else []:
                if m["to"] == vehicle and m["received_t"] is not None:
                    self.queue.append((float(m["received_t"]), 1, float(m["t"]), _peer_message(kind, m)))
        self.queue.sort(key=lambda q: q[:3], reverse=True)  # popped from the end: earliest first

    def _join(self, planner: RulesAvoider) -> None:
        planner.join_utm(self.vehicle, self.lost_after, self.peer_link)
        self.joined = planner

    def deliver(self, flying: Planner | None, t: float) -> None:
        """Hand ``flying`` the directives and peer messages handed over by ``t`` [s] (before the
        calls at ``t``); a rules planner that has not joined joins first; without a rules
        planner flying they go unheard. What the planner would send is dropped."""
        while self.queue and self.queue[-1][0] <= t + 1e-9:
            received, _, _, m = self.queue.pop()
            if isinstance(flying, RulesAvoider):
                if flying is not self.joined:
                    self._join(flying)
                if isinstance(m, Directive):
                    flying.receive_directive(m, received)
                elif flying.peers is not None:
                    flying.receive_peer(m, received)
        if isinstance(flying, RulesAvoider):
            flying.peer_outbox()


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
    """How the re-run's plan differs from the recorded one (status, vertices, due times,
    labels, commanded airspeeds, decision events where recorded); updates the report's largest
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
    if not _same_airspeeds(rec.get("airspeeds"), new.airspeeds):
        why.append("commanded airspeeds differ")
    events = rec.get("diagnostics", {}).get("events")
    if events is not None and events != new.diagnostics.get("events"):
        why.append("decision events differ")
    return why


def _same_airspeeds(old: list[float] | None, new: np.ndarray | None) -> bool:
    """Whether a recorded plan's commanded airspeeds [m/s] (None: none) are the re-run's."""
    if old is None or new is None:
        return old is None and new is None
    return bool(np.allclose(old, new))
