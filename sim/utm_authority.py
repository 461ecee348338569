"""The central UTM authority of one static airspace cluster (spec §7.1, §7.3, §7.4): decision frames,
position notifications with filed mission plans, collision cases computed centrally, directives,
acknowledgements and breach reports, every message over each vehicle's modelled link
(:mod:`sim.utm_link`) and on its own MCAP topic.

UTM frame i starts at ``i * frame`` [s] (6.181). At its start the authority takes the newest
notification of every vehicle that arrived during frame i-1 or earlier and is not older than
``lost_after`` (a vehicle silent for longer has lost its link: it is left out, its cases close)
of the vehicles past their start transient (the rules' ``settle`` and ``established_speed``),
updates its case book (:class:`avoidance.utm.cases.CaseBook`: chaining, roundabouts; positions
adjusted to the frame time along the filed plans = trajectory intersection, 6.187-6.189), and
sends every vehicle a directive with its active cases (a heartbeat when it has none).
Then every vehicle sends its notification of frame i: the estimate (GCF) and its filed plan, the
remaining mission waypoints from the estimate at cruise speed sampled every frame. Joined
vehicles (rules planners, :meth:`avoidance.rules.planner.RulesAvoider.join_utm`) obey and
acknowledge every directive they receive; the others only notify (their directives go unheard).
A rules planner built anew during the run (a ground-station mode change back to AUTO, a mission
upload) joins when the next directive reaches it; while a ground-station mode planner (HOLD,
GUIDED) flies, the vehicle's directives go unheard and unacknowledged.

With ``utm.weather`` the weather service's nowcasts come to the authority (not to the vehicles):
each directive also carries the weather cases (§7.5) of the cells the recipient's filed route
(from its notified position through its remaining mission waypoints) crosses at its notified
height, with the weather band of its registration.

Mandates (``utm.mandate``, :mod:`avoidance.utm.mandate`): every directive to a vehicle carries
the mandates in force for it (keep clear of a cylinder); the vehicle obeys and acknowledges them
(the acknowledgement lists the ids it obeys); a notified position inside one is a breach.

Clusters (``utm.cluster``): one authority per box. A vehicle sends its notification to every
authority whose box grown by ``utm.handover`` holds its estimate (and once more to one it has just
left, which then counts it as left rather than lost); each authority computes the cases of the
vehicles notified within its band, and directs the vehicles :class:`sim.utm_airspace.UtmAirspace`
assigns it (the box holding a vehicle's newest notification). A pair across a boundary is thus
known to both authorities before either vehicle crosses, and a vehicle crossing is directed by
the next authority from the next frame on. Without clusters one authority holds every vehicle.
The frame numbers are the same for every authority (frame i starts at ``i * frame``), so a
vehicle's inbox orders directives across a hand-over.

Topics (every message names its ``cluster``, ``all`` without clusters): ``/utm/notification``,
``/utm/frame``, ``/utm/directive``, ``/utm/ack``, ``/utm/link`` (the authority's view of a
vehicle's link: lost / up / left its band), ``/utm/breach`` (an active case whose
notified separation is below its margin, once per case chain; a notified position inside a
mandate's cylinder, once per mandate), ``/utm/spoof`` (forged cases injected on a vehicle's
downlink, scenario ``utm.spoof``). Frames: GCF (ENU) [m] from the scenario origin, sim seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from avoidance.rules.planner import RulesAvoider
from avoidance.utm.cases import CaseBook, SharedHeads, as_roundabout
from avoidance.utm.collision_case import CollisionCase, Encounter, Role, UtmConfig
from avoidance.utm.directives import Directive
from avoidance.utm.mandate import Mandate
from avoidance.utm.notification import PositionNotification, Registration
from avoidance.utm.weather_case import WeatherCase, crossing, weather_cases
from sim import log_schemas as S
from sim.core.frames import ned_to_enu
from sim.core.threats import StormSnapshot
from sim.mcap_log import McapLog
from sim.scenario import Utm, UtmCluster, UtmMandate, UtmSpoof
from sim.utm_link import Link, Queue
from sim.vehicle import Vehicle

_META = {"frame": "GCF = ENU [m] from the scenario origin"}


@dataclass(slots=True)
class AirspaceState:
    """What the authorities of one airspace share over their ground network
    (:class:`sim.utm_airspace.UtmAirspace`): per vehicle the send time of its first
    notification any of them took [s] (the start transient counts from there) and the authority
    directing it this frame (None: uncontrolled airspace), the open cases' heads (None with
    one authority) and the chains whose breach has been reported."""

    first_heard: dict[str, float] = field(default_factory=dict)
    director: dict[str, str | None] = field(default_factory=dict)
    heads: SharedHeads | None = None
    breached: set[tuple[tuple[str, str], float | None]] = field(default_factory=set)  # (pair, head time)


@dataclass(slots=True)
class Member:
    """A vehicle as the authority knows it: its link, filed registration, newest notification,
    newest acknowledged frame and whether its link counts as lost."""

    vehicle: Vehicle
    link: Link
    registration: Registration
    planner: RulesAvoider | None  # the rules planner joined last (None: a vehicle that only notifies)
    down: Queue
    last_note: PositionNotification | None = None
    last_ack: int = -1
    lost: bool = True  # no fresh notification (before the first one, too)
    established: bool = False  # past its start transient (:meth:`UtmAuthority._established`)
    peer_link: bool = False  # it has a vehicle-to-vehicle link (response mode)
    sent: bool = False  # its last notification went to this authority (inside the band)
    home_since: int | None = None  # frame it has been directed from since (None: not directed here)

    def obeying(self, lost_after: float) -> RulesAvoider | None:
        """The planner that obeys and acknowledges directives now: the vehicle's rules planner,
        joined to the authority when it is new (a ground-station mode change or mission upload
        builds one); None while a mode planner (HOLD, GUIDED) flies or for other planners."""
        p = self.vehicle.planner
        if not isinstance(p, RulesAvoider):
            return None
        if p is not self.planner:
            p.join_utm(self.vehicle.name, lost_after, self.peer_link)
            self.planner = p
        return p


class UtmAuthority:
    """The authority of one airspace ``cluster`` (None: the whole airspace). Rules vehicles join with their filed
    registration (:meth:`RulesAvoider.join_utm`); the case parameters (time margin, closing
    hysteresis, doubts) are those the first of them files, so the authority and the vehicles'
    virtual UTMs compute cases alike. Other vehicles notify with the default registration
    (thesis margins, unscaled) and obey nothing."""

    def __init__(
        self,
        cfg: Utm,
        vehicles: list[Vehicle],
        links: dict[str, Link],
        log: McapLog,
        origin_alt: float,
        tick_hz: float,
        peer_linked: frozenset[str] = frozenset(),
        cluster: UtmCluster | None = None,
        airspace: AirspaceState | None = None,
    ):
        """``tick_hz``: the rate :meth:`tick` is called at (the log rate); ``peer_linked``: the
        vehicles with a vehicle-to-vehicle link; ``cluster``: the airspace box it holds;
        ``airspace``: the state shared with the other authorities of the airspace (its director
        assignment comes from :class:`sim.utm_airspace.UtmAirspace`)."""
        self.cfg, self.log, self.origin_alt, self.tick_hz = cfg, log, origin_alt, tick_hz
        self.cluster = cluster
        self.id = cluster.id if cluster is not None else "all"
        self.airspace = airspace if airspace is not None else AirspaceState()
        self.members: dict[str, Member] = {}
        book_cfg: UtmConfig | None = None
        for v in vehicles:
            p = v.planner if isinstance(v.planner, RulesAvoider) else None
            peer = v.name in peer_linked
            reg = p.join_utm(v.name, cfg.lost_after, peer) if p is not None else Registration(v.name)
            if p is not None and book_cfg is None:
                book_cfg = p.book.cfg
            self.members[v.name] = Member(v, links[v.name], reg, p, Queue(), peer_link=peer)
        self.mandates = [(m.vehicle, self._mandate(m)) for m in cfg.mandate]
        self.book = CaseBook(book_cfg or UtmConfig(), shared=self.airspace.heads)
        self.up = Queue()
        self.frame_no = 0
        self.storms: list[StormSnapshot] = []  # the newest nowcast, with ``utm.weather``
        self._mandate_breached: set[str] = set()
        # the frame between its two phases: the notifications used and the cases opened
        self._frame: tuple[list[PositionNotification], list[CollisionCase]] = ([], [])

    def deliver(self, t: float) -> None:
        """Deliver what arrived by ``t`` [s] (notifications and acknowledgements to the authority,
        directives to the vehicles)."""
        for kind, name, msg in self.up.due(t):
            m = self.members[name]
            if kind == "ack":
                m.last_ack = max(m.last_ack, msg["frame"])
                self.log.write_json("/utm/ack", t, {"t": t, "cluster": self.id, "from": name, **msg}, S.UTM_ACK)
            elif m.last_note is None or msg.t > m.last_note.t:
                m.last_note = msg
                self._log_notification(t, msg)
        for name, m in self.members.items():
            for d in m.down.due(t):
                p = m.obeying(self.cfg.lost_after)
                if p is not None:
                    self._send_up(t, name, ("ack", name, p.receive_directive(d, t)))

    def frame_due(self, t: float) -> bool:
        """Whether decision frame ``frame_no`` starts at or before ``t`` [s]."""
        return t + 1e-9 >= self.frame_no * self.cfg.frame

    def assess(self, t: float) -> None:
        """The first phase of decision frame ``frame_no`` at ``t`` [s]: the cases from frame
        i-1's notifications, chained, nothing closed yet (:meth:`direct` closes)."""
        notes = []
        for name, m in self.members.items():
            note = m.last_note
            stale = note is None or t - note.t > self.cfg.lost_after
            # left the band: notified outside it, or silent and predicted outside by now
            inside = note is not None and self._in_band(note.pos)
            left = note is not None and not (inside and (not stale or self._in_band(note.adjusted(t).pos)))
            fresh = not stale and not left
            if fresh == m.lost:
                m.lost = not fresh
                self._log_link(t, name, "left" if left else "lost" if m.lost else "up")
            if fresh and note is not None and self._established(m, note):
                notes.append(note)
        self._frame = (notes, self.book.assess(notes, t))

    def direct(self, t: float, closing: set[tuple[str, str]]) -> None:
        """The second phase of the frame at ``t`` [s]: close the chains of ``closing`` (the pairs
        the airspace's books close together, :class:`sim.utm_airspace.UtmAirspace`), log the
        frame, send the directives, then this frame's notifications."""
        notes, opened = self._frame
        closed = self.book.close(closing)
        rbs = {u: rb for rb in self.book.roundabouts() for u in rb.members}
        active = self.book.active()
        self._report_breaches(t, active)
        self._report_mandate_breaches(t, notes)
        self.log.write_json(
            "/utm/frame",
            t,
            {
                "t": t,
                "cluster": self.id,
                "frame": self.frame_no,
                "notified": sorted(n.id for n in notes),
                "opened": [c.record() for c in opened],
                "closed": [c.record() for c in closed],
                "active": [c.record() for c in active],
                "roundabouts": [
                    {"members": sorted(r.members), "centre_enu": r.centre.tolist(), "margin_m": r.margin}
                    for r in self.book.roundabouts()
                ],
                "unacknowledged": self._unacknowledged(),
            },
            S.UTM_FRAME,
            _META,
        )
        for name, m in self.members.items():
            if not self._home(m):
                m.home_since = None
                continue
            if m.home_since is None:
                m.home_since = self.frame_no
            cases = [as_roundabout(c, rbs[name]) if name in rbs else c for c in active if name in c.ids]
            mandates = tuple(md for to, md in self.mandates if to == name and md.active(t))
            d = Directive(self.frame_no, t, name, tuple(cases) + self._spoofed(t, name), self._weather(m, t), mandates)
            self._send_down(t, m, d)
        for name, m in self.members.items():
            note = self._notification(m, t)
            inside = self._in_band(note.pos)
            if inside or m.sent:  # the vehicle tells an authority it has just left, once
                self._send_up(t, name, ("note", name, note))
            m.sent = inside
        self.frame_no += 1

    def _in_band(self, pos: np.ndarray) -> bool:
        """Whether a GCF position [m] lies in the cluster's box grown by ``handover``."""
        return self.cluster is None or self.cluster.contains(float(pos[0]), float(pos[1]), self.cfg.handover)

    def _home(self, m: Member) -> bool:
        """Whether this authority directs ``m`` this frame (:attr:`AirspaceState.director`)."""
        return self.airspace.director.get(m.vehicle.name) == self.id

    def holds(self, pos: np.ndarray) -> bool:
        """Whether the GCF position [m] lies in this authority's box (anywhere without one)."""
        return self.cluster is None or self.cluster.contains(float(pos[0]), float(pos[1]))

    def _log_link(self, t: float, name: str, state: str) -> None:
        self.log.write_json("/utm/link", t, {"t": t, "cluster": self.id, "vehicle": name, "state": state}, S.UTM_LINK)
        self.log.event(t, f"{self._who}: link to {name} {state}", "info" if state == "up" else "warning", "utm")

    @property
    def _who(self) -> str:
        return "utm" if self.cluster is None else f"utm {self.id}"

    def _established(self, m: Member, note: PositionNotification) -> bool:
        """Whether the vehicle takes part in cases: as in its own *detect* rule, once it has
        flown its rules' ``settle`` [s] since its first notification (to any authority) and reached their
        ``established_speed`` share of its cruise speed (start transients make early headings
        meaningless, and the head case fixes the roles); then for good."""
        first = self.airspace.first_heard.setdefault(m.vehicle.name, note.t)
        if not m.established and m.planner is not None:
            rules = m.planner.rules
            m.established = (
                note.t >= first + rules.settle and note.speed >= rules.established_speed * m.registration.max_cruise
            )
        return m.established or m.planner is None

    def _weather(self, m: Member, t: float) -> tuple[WeatherCase, ...]:
        """The weather cases of the cells ``m``'s filed route crosses at frame time ``t`` [s]
        (none while its link is lost); a moving cell swept over the time the route takes at
        cruise speed. The route is the mission's (notified position, then the waypoints not yet
        reached), not the plan flown that :meth:`_notification` files for traffic: a plan that
        detours around a cell does not cross it, and the case would end while the detour is flown."""
        note = m.last_note
        if not self.storms or note is None or m.lost:
            return ()
        cases = weather_cases(self.storms, t, m.registration.margins.weather, up_m=float(note.pos[2]))
        mission = m.vehicle.mission
        route = np.vstack([note.pos, ned_to_enu(mission.waypoints[mission.next_index :])])
        length = float(np.linalg.norm(np.diff(route, axis=0), axis=1).sum())
        return tuple(crossing(cases, route, length / mission.cruise_speed))

    def _unacknowledged(self) -> list[str]:
        """Vehicles directed here for more than ``lost_after`` whose newest acknowledgement is
        older than that."""
        old = self.frame_no - max(1, round(self.cfg.lost_after / self.cfg.frame))
        return sorted(
            n
            for n, m in self.members.items()
            if m.planner is not None and m.home_since is not None and m.home_since <= old and m.last_ack < old
        )

    def _notification(self, m: Member, t: float) -> PositionNotification:
        """The vehicle's notification at ``t`` [s] with its filed plan (intent, 6.187): the
        vertices of the plan it flies that are still ahead (a roundabout member's circle, a
        give-way turn), then its mission waypoints not yet reached, at its cruise speed: the
        authority predicts each UAS along the path it is flying, not along a mission leg it has
        left."""
        v, est = m.vehicle, m.vehicle.estimate
        horizon = self.book.cfg.time_margin + self.cfg.lost_after
        plan = v.follower.plan
        ahead = plan.positions[plan.times > t] if plan is not None else np.empty((0, 3))
        wps = np.vstack([ahead, v.mission.waypoints[v.mission.next_index :]])
        note = PositionNotification(t, m.registration, ned_to_enu(est.pos_ned), ned_to_enu(est.vel_ned), True)
        return note.with_intent(ned_to_enu(wps), horizon, self.cfg.frame, v.mission.cruise_speed)

    def _send_up(self, t: float, name: str, msg: tuple) -> None:
        due = self.members[name].link.arrival(t)
        if due is not None:
            self.up.put(due, msg)

    def _send_down(self, t: float, m: Member, d: Directive) -> None:
        due = m.link.arrival(t)
        self.log.write_json(
            "/utm/directive",
            t,
            {
                "t": t,
                "cluster": self.id,
                "frame": d.frame,
                "to": d.to,
                "received_t": self._handed(due),
                "cases": [c.record() for c in d.cases],
                "weather": [w.record() for w in d.weather],
                "mandates": [md.record() for md in d.mandates],
            },
            S.UTM_DIRECTIVE,
            _META,
        )
        if due is not None:
            m.down.put(due, d)

    def _handed(self, due: float | None) -> float | None:
        """When a message arriving at ``due`` [s] is handed over: the first tick at or after it."""
        return None if due is None else math.ceil(due * self.tick_hz - 1e-6) / self.tick_hz

    def _spoofed(self, t: float, name: str) -> tuple[CollisionCase, ...]:
        """Forged head-on cases injected on ``name``'s downlink (scenario ``utm.spoof``)."""
        out = []
        for s in self.cfg.spoof:
            if s.vehicle != name or t < s.at or (s.duration is not None and t >= s.at + s.duration):
                continue
            c = self._forged(s, t)
            out.append(c)
            record = {"t": t, "cluster": self.id, "to": name, "case": c.record()}
            self.log.write_json("/utm/spoof", t, record, S.UTM_SPOOF, _META)
        return tuple(out)

    def _forged(self, s: UtmSpoof, t: float) -> CollisionCase:
        cp = np.array([s.east, s.north, s.altitude - self.origin_alt])
        own = self.members[s.vehicle].last_note
        sep = float(np.linalg.norm(own.pos - cp)) if own is not None else np.inf
        return CollisionCase(
            t,
            (s.vehicle, s.peer),
            Encounter.HEAD_ON,
            180.0,
            (Role.ROUNDABOUT, Role.ROUNDABOUT),
            cp,
            0.0,
            0.0,
            s.margin,
            True,
            head=t,
            separation=sep,
        )

    def _report_breaches(self, t: float, active: list[CollisionCase]) -> None:
        """Monitor adherence: a case whose separation is below its margin is a breach, reported
        once per chain in the airspace (by the first authority holding it that sees it)."""
        for c in active:
            key = (c.ids, c.head)
            if c.separation < c.margin and key not in self.airspace.breached:
                self.airspace.breached.add(key)
                record = {"t": t, "cluster": self.id, "case": c.record()}
                self.log.write_json("/utm/breach", t, record, S.UTM_BREACH, _META)
                what = f"breach {c.ids[0]}-{c.ids[1]}: {c.separation:.1f} m < {c.margin:.1f} m"
                self.log.event(t, f"{self._who}: {what}", "warning", "utm")

    def _mandate(self, m: UtmMandate) -> Mandate:
        """The mandate of a scenario entry (GCF centre, heights above the origin)."""
        lo = -math.inf if m.altitude_min is None else m.altitude_min - self.origin_alt
        hi = math.inf if m.altitude_max is None else m.altitude_max - self.origin_alt
        end = None if m.duration is None else m.at + m.duration
        return Mandate(m.id, m.at, end, np.array([m.east, m.north]), m.radius, lo, hi)

    def _report_mandate_breaches(self, t: float, notes: list[PositionNotification]) -> None:
        """Monitor the mandates: a notified position inside a mandate in force is a breach."""
        where = {n.id: n.pos for n in notes if self._home(self.members[n.id])}
        for to, md in self.mandates:
            if md.id in self._mandate_breached or to not in where or not md.active(t) or not md.inside(where[to]):
                continue
            self._mandate_breached.add(md.id)
            record = {"t": t, "cluster": self.id, "vehicle": to, "mandate": md.record()}
            self.log.write_json("/utm/breach", t, record, S.UTM_BREACH, _META)
            self.log.event(t, f"{self._who}: breach of mandate {md.id} by {to}", "warning", "utm")

    def _log_notification(self, t: float, n: PositionNotification) -> None:
        self.log.write_json(
            "/utm/notification",
            t,
            {
                "t": t,
                "cluster": self.id,
                "sent_t": n.t,
                "from": n.id,
                "pos_enu": n.pos,
                "vel_enu": n.vel,
                "plan_enu": n.trajectory if n.trajectory is not None else [],
            },
            S.UTM_NOTIFICATION,
            _META,
        )
