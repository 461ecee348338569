"""``RulesAvoider``: the reach-set avoider with the rules of the air of a cooperative UAS
(spec §7): a ``reachset`` planner whose options carry a ``rules`` table.

Per decision frame (one per movement period):
1. notifications: the own UAS from its estimate, every cooperative peer from its surveillance
   track (the world's latency, dropout and noise) plus its filed registration;
2. decision point *before avoidance run*: the virtual UTM's case book is updated over all pairs
   (chaining, roundabouts) and the own cases to resolve are selected;
3. the mission-control run sees as intruders the non-cooperative traffic, cooperative peers the
   rules cannot assess (hovering, no common flight level) and peers handed to the emergency
   avoidance (unresolved cases, deadlocks); the other cooperative peers are not (they are
   resolved by the rules in navigation mode, spec §6.2 step 5b) — unless another threat holds
   the vehicle in emergency mode, whose runs have no rule restrictions: there every peer is an
   intruder;
4. decision point *trajectory restrictions* (``MissionControl(restrict=...)``): the manoeuvre
   rules disable navigation trajectories; an overtake flies its divergence / convergence waypoint
   in place of the mission goal for that run;
5. decision point *after avoidance run*: deadlock -> emergency, resolution report.
Under a central UTM (:meth:`join_utm`) the directives' cases are merged in *detect*; with the UTM
link lost the UAS claims its cases to its peers and flies the acknowledged ones (response mode,
:mod:`avoidance.utm.response`) or, hearing no peer, its own (blind); the mandates in force are
keep-out geofences (hard constraints) of every run, the emergency ones too.
Every case and rule decision is an event ``rule:<code>[:<pair>:<encounter>:<role>]`` of the
decision (logged in ``/<vehicle>/plan/decision``) and a record in :attr:`rules_record`
(``/<vehicle>/plan/rules``). Frames: NED at the boundary, GCF (ENU) inside; sim seconds.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from avoidance.reachset.config import DEFAULT_AVOIDANCE, AvoidanceConfig
from avoidance.reachset.gridrun import GridRun
from avoidance.reachset.mission import Decision
from avoidance.reachset.movement import KinState, SegmentedMovementAutomaton
from avoidance.reachset.planner import ReachSetAvoider
from avoidance.rules.config import RulesConfig
from avoidance.rules.engine import DecisionPoint, RuleContext, RuleEngine
from avoidance.rules.rules_of_air import make_rules
from avoidance.utm.cases import CaseBook
from avoidance.utm.collision_case import Role
from avoidance.utm.directives import Directive, UtmInbox
from avoidance.utm.notification import PositionNotification, Registration, from_track
from avoidance.utm.response import PeerMessage, PeerTalk
from avoidance.utm.weather_case import weather_cases
from sim.core.frames import ned_to_enu
from sim.core.mission import Mission
from sim.core.plan import Plan, Threats
from sim.core.state import VehicleState

OWN = "self"  # the own UAS' id in its case book (peers are named by their track ids)
HOLD_FRAMES = 10  # at most this many soft-deadlock hovers in a row (a peer that holds course may never pass)


class RulesAvoider(ReachSetAvoider):
    def __init__(
        self,
        mission: Mission,
        sma: SegmentedMovementAutomaton,
        rules: RulesConfig,
        cfg: AvoidanceConfig = DEFAULT_AVOIDANCE,
        cache_dir: Path | None = None,
        turns_in_place: bool = False,
    ):
        """``cfg``'s navigation reach set is replaced by the rules' ACAS-like one;
        ``turns_in_place`` as in :class:`ReachSetAvoider`."""
        cfg = rules.avoidance(cfg)
        super().__init__(
            mission,
            sma,
            cfg,
            cache_dir,
            restrict=self._restrict,
            turns_in_place=turns_in_place,
            hold=self._hold if turns_in_place and rules.hold else None,
        )
        self.rules = rules
        self.engine = RuleEngine(make_rules(rules.enabled))
        cruise = sma.automata[sma.active_index(KinState(np.zeros(3), np.zeros(3), 0.0, self.speed))].table.config
        self.length = cruise.length
        self.registration = rules.registration(OWN, self.speed)
        self.frame = cruise.period
        self.book = CaseBook(rules.utm(cfg.grid.d_range[1] * self.length, self.speed))
        self.emergency: set[str] = set()
        self.rules_record: dict | None = None
        self._ctx: RuleContext | None = None
        self._deadlock_frames = 0
        self._held_frames = 0  # consecutive frames hovering in a soft deadlock (:meth:`_hold`)
        self._unresolved: set = set()
        self._start: float | None = None
        self._progress: dict[str, int] = {}  # peers' filed plans: index of the next waypoint
        self.utm: UtmInbox | None = None  # set when a central UTM authority directs this UAS
        self.peers: PeerTalk | None = None  # set when the UAS has a vehicle-to-vehicle link

    def join_utm(self, name: str, lost_after: float, peer_link: bool = False) -> Registration:
        """Register with a central UTM as ``name``: directives are merged with the own cases from
        now on; the link counts as lost after ``lost_after`` [s] without a directive; with a
        ``peer_link`` (vehicle-to-vehicle) a lost UTM link means response mode while peers are
        heard. Returns the registration filed. Joining again (the authority of another airspace
        cluster) keeps the inbox: directives of every authority arrive in it."""
        if self.utm is None:
            self.utm = UtmInbox(OWN, lost_after)
            self.peers = PeerTalk(name, OWN, lost_after) if peer_link else None
        return dataclasses.replace(self.registration, id=name)

    def receive_peer(self, m: PeerMessage, t: float) -> list[PeerMessage]:
        """A message from a peer arrived at ``t`` [s]; returns what to send at once (the
        acknowledgement of a claim)."""
        if self.peers is None:
            raise RuntimeError("receive_peer without a peer link (join_utm)")
        self.peers.receive(m, t)
        return self.peers.drain()

    def peer_outbox(self) -> list[PeerMessage]:
        """The messages to send to peers now (this frame's claims)."""
        return [] if self.peers is None else self.peers.drain()

    def receive_directive(self, d: Directive, t: float) -> dict:
        """A UTM directive arrived at ``t`` [s]; returns the acknowledgement."""
        if self.utm is None:
            raise RuntimeError("receive_directive before join_utm")
        return self.utm.receive(d, t)

    def notifications(self, estimate: VehicleState, threats: Threats, t: float) -> list[PositionNotification]:
        own = PositionNotification(t, self.registration, ned_to_enu(estimate.pos_ned), ned_to_enu(estimate.vel_ned))
        peers = [
            self._with_plan(from_track(tr, self.rules.registration(tr.id, self.speed)))
            for tr in threats.intruders
            if tr.cooperative
        ]
        return [own, *peers]

    def _with_plan(self, note: PositionNotification) -> PositionNotification:
        """A peer with a filed plan (``RulesConfig.plans``) predicted along its remaining legs
        over the UTM's time margin (intent sharing); its progress is kept per peer."""
        plan = self.rules.plans.get(note.id)
        if plan is None:
            return note
        wps = np.array([[e, n, note.pos[2]] for n, e in plan], float)  # GCF: x east, y north, at its altitude
        k = self._progress.get(note.id, 0)
        while k < len(wps) and float(np.hypot(*(wps[k, :2] - note.pos[:2]))) <= 2.0 * self.length:
            k += 1
        self._progress[note.id] = k
        return note.with_intent(wps[k:], self.book.cfg.time_margin, self.frame)

    def plan(self, estimate: VehicleState, threats: Threats, t: float) -> Plan:
        if self._last is not None and not self.frame_due(t):
            return self._last
        ctx = RuleContext(
            OWN,
            t,
            self.rules,
            self.book,
            self.notifications(estimate, threats, t),
            self.length,
            self.frame,
            emergency=set(self.emergency),
            deadlock_frames=self._deadlock_frames,
            unresolved=self._unresolved,
            start=self._start if self._start is not None else t,
            utm=self.utm,
            peers=self.peers,
        )
        if self.utm is not None:
            mode = self.utm.update(t, self.peers is not None and self.peers.heard(t))
            if mode is not None:
                ctx.record(f"utm_{mode.value}")
            threats = self._mandated(threats, t, ctx)
        self._ctx = ctx
        self._start = ctx.start
        weather = self.engine.enabled("weather")
        if weather:  # storm cells become weather cases, handled by the rules instead of the run's constraints
            margin = self.rules.weather_margin * self.rules.unit
            own = weather_cases(threats.storms, t, margin, up_m=-float(estimate.pos_ned[2]))
            directed = self.utm.weather() if self.utm is not None else []  # the UTM's replace own ones of a cell
            ctx.events.extend(f"rule:utm_weather:{w.id}" for w in directed)
            ctx.weather = [w for w in own if w.id not in {d.id for d in directed}] + directed
        ctl = self.control
        ctx.goal = ctl.waypoints[min(max(ctl.goal, self.mission.next_index), len(ctl.waypoints) - 1)]
        self.engine.invoke(DecisionPoint.BEFORE_AVOIDANCE_RUN, ctx)
        sensed = dataclasses.replace(
            threats,
            intruders=[tr for tr in threats.intruders if tr.id not in ctx.managed or tr.id in ctx.emergency],
            storms=[] if weather else threats.storms,
        )
        goal = max(ctl.goal, self.mission.next_index)
        override = ctx.goal_override if goal < len(ctl.waypoints) else None  # the rules' waypoint
        plan = self.decide(estimate, sensed, t, override, emergency_threats=threats)
        if ctx.speed is not None:  # 6.202: slower along the plan (the follower honours it)
            plan.speed = ctx.speed
            plan.diagnostics["speed_mps"] = ctx.speed
        ctx.decision = self.last_decision
        d = ctx.current_decision()
        self.engine.invoke(DecisionPoint.AFTER_AVOIDANCE_RUN, ctx)
        self.emergency, self._deadlock_frames = ctx.emergency, ctx.deadlock_frames
        if ctx.held or d.selected >= 0:  # the hold count ends with a path, not with a frame flown on blocked
            self._held_frames = self._held_frames + 1 if ctx.held else 0
        d.events.extend(ctx.events)
        plan.diagnostics["events"] = ";".join(d.events)
        self.rules_record = {
            "t": t,
            "events": list(ctx.events),
            "decisions": ctx.decisions,
            "cases": [c.record() for c in self.book.active(OWN)],
            "roundabouts": [
                {"members": sorted(r.members), "centre_enu": r.centre.tolist(), "margin_m": r.margin}
                for r in self.book.roundabouts()
            ],
            "emergency": sorted(ctx.emergency),
            "weather": [w.record() for w in ctx.weather],
            "mode": d.mode.value,
            "utm_link": None if self.utm is None else self.utm.mode.value,
        }
        self._ctx = None
        return plan

    def _mandated(self, threats: Threats, t: float, ctx: RuleContext) -> Threats:
        """``threats`` with the UTM mandates in force as keep-out geofences (hard constraints of
        every run, the emergency ones too), each a ``rule:utm_mandate:<id>`` event."""
        assert self.utm is not None
        mandates = self.utm.in_force(t)
        if not mandates:
            return threats
        for m in mandates:
            ctx.events.append(f"rule:utm_mandate:{m.id}")
            ctx.decisions.append({"rule": "utm_mandate", "mandate": m.record()})
        return dataclasses.replace(threats, geofences=[*threats.geofences, *(m.geofence() for m in mandates)])

    def _hold(self, d: Decision, s_next: KinState) -> bool:
        """A soft deadlock of a vehicle that hovers: hover at the grid origin (``s_next``, GCF)
        for this period when every peer of the cases it resolves holds its course (right of way,
        overtaken: it flies on, so waiting resolves the case) and, over two periods (the hover
        and the next), predicted linearly from its notification, keeps the case margin + bloat
        from there (or, already closer, comes no closer); at most ``HOLD_FRAMES`` frames in a row.
        The give-way UAS of a shallow converging case at equal speeds finds no restricted path
        while the peer is ahead of it (docs/encounters.md finding 18); waiting lets the peer pass,
        where flying the old plan on took it into the margin. Not with a peer that resolves too
        (head-on, roundabout): both would wait. Event ``rule:hold``."""
        ctx = self._ctx
        if ctx is None or not ctx.resolve or self._held_frames >= HOLD_FRAMES:
            return False
        if any(c.role_of(c.other(ctx.uas)) not in (Role.RIGHT_OF_WAY, Role.OVERTAKEN) for c in ctx.resolve):
            return False  # a peer that resolves too may wait as well (head-on, roundabout)
        t = np.linspace(0.0, 2.0 * self.frame, 21)[:, None]
        for c in ctx.resolve:
            peer = ctx.note(c.other(ctx.uas))
            if peer is None:
                return False
            p = peer.adjusted(d.t_grid)
            gap = np.linalg.norm(p.pos + t * p.vel - s_next.pos, axis=1)
            if gap.min() < min(c.margin + ctx.cfg.bloat * ctx.unit, gap[0]) - 1e-9:
                return False
        ctx.held = True
        ctx.record("hold", peers=sorted(c.other(ctx.uas) for c in ctx.resolve), frames=self._held_frames + 1)
        return True

    def _restrict(self, d: Decision, run: GridRun) -> np.ndarray | None:
        """Decision point *trajectory restrictions* on the navigation run."""
        ctx = self._ctx
        if ctx is None:
            return None
        ctx.decision, ctx.run = d, run
        self.engine.invoke(DecisionPoint.TRAJECTORY_RESTRICTIONS, ctx)
        ctx.path_found = None if ctx.disabled is None else bool((run.fused.node_ok & ~ctx.disabled).any())
        return ctx.disabled
