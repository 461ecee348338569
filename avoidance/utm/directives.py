"""Vehicle side of the central UTM (spec §7.1, §7.7 "Detect collision cases"): the directives a
UAS receives over its C2/UTM link, its link state, and the merge of the UTM's cases with its own.

A directive of UTM frame ``frame`` (frame time ``t`` [s]) lists the recipient's active collision
cases as the authority computed them (ids with the recipient renamed to the UAS' own id) and,
when the authority owns the weather feed, the weather cases of the cells its route crosses
(§7.5); the newest weather cases are kept across a lost link (the last weather picture). The
UAS acknowledges every directive it receives. When no directive has arrived for ``lost_after``
[s] the link is lost (spec §7.1, non-cooperative): the UAS is in *response* mode while it hears
its peers over the vehicle-to-vehicle link (roles agreed by acknowledged claims,
:mod:`avoidance.utm.response`), else *blind*: the rules of the air on its own cases only (its
virtual UTM), until a directive arrives again. Directives also carry *mandates*
(:mod:`avoidance.utm.mandate`): each is obeyed from its receipt to its end, across a lost link,
and acknowledged with every directive while in force.

Merge (tab. 6.10), per peer:
- UTM case and own case: the UTM's collision point, encounter and roles (reported when the
  points differ by the case's margin or more), the larger margin;
- UTM case only: obeyed when the UAS' own surveillance confirms the peer (it has a track of it),
  else ignored until confirmed (anti-spoofing: a forged case about a vehicle that does not exist
  moves nobody);
- own case only: kept (reported to the UTM).
Frames and units: GCF (ENU) [m], sim seconds [s].
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np

from avoidance.utm.collision_case import CollisionCase
from avoidance.utm.mandate import Mandate
from avoidance.utm.response import renamed
from avoidance.utm.weather_case import WeatherCase


class LinkMode(str, Enum):
    COOPERATIVE = "cooperative"  # directives arrive: UTM cases merged with the own ones
    RESPONSE = "response"  # UTM link lost, peers heard: cases agreed with them by acknowledged claims
    BLIND = "blind"  # UTM link lost, no peer heard: rules of the air on the own cases only


@dataclass(frozen=True, slots=True)
class Directive:
    """The UTM's commands of one frame for one UAS: its active collision cases (resolutions),
    its weather cases (GCF) and the mandates in force for it."""

    frame: int
    t: float  # frame time [s]
    to: str  # the recipient's registration id
    cases: tuple[CollisionCase, ...] = ()
    weather: tuple[WeatherCase, ...] = ()
    mandates: tuple[Mandate, ...] = ()


@dataclass(frozen=True, slots=True)
class Merge:
    """The merged cases and what the merge decided, per peer: ``utm`` obeyed UTM cases,
    ``moved`` UTM points that differ from the own ones, ``unconfirmed`` ignored UTM-only cases,
    ``own_only`` own cases the UTM does not have."""

    cases: list[CollisionCase]
    utm: list[CollisionCase] = field(default_factory=list)
    moved: list[CollisionCase] = field(default_factory=list)
    unconfirmed: list[CollisionCase] = field(default_factory=list)
    own_only: list[CollisionCase] = field(default_factory=list)


def merge_cases(own: list[CollisionCase], utm: list[CollisionCase], uas: str, confirmed: set[str]) -> Merge:
    """Merge the UTM's cases of ``uas`` with its own (module docstring); ``confirmed`` = the
    peers the UAS' own surveillance tracks."""
    mine = {c.other(uas): c for c in own}
    theirs = {c.other(uas): c for c in utm}
    out = Merge([])
    for peer, c in sorted(mine.items()):
        u = theirs.get(peer)
        if u is None:
            out.cases.append(c)
            out.own_only.append(c)
            continue
        merged = replace(
            c,
            encounter=u.encounter,
            alpha_deg=u.alpha_deg,
            collision_point=u.collision_point,
            roles=(u.role_of(c.ids[0]), u.role_of(c.ids[1])),
            margin=max(c.margin, u.margin),
        )
        out.cases.append(merged)
        out.utm.append(merged)
        if float(np.linalg.norm(u.collision_point - c.collision_point)) >= merged.margin:
            out.moved.append(merged)
    for peer, u in sorted(theirs.items()):
        if peer in mine:
            continue
        if peer in confirmed:
            out.cases.append(u)
            out.utm.append(u)
        else:
            out.unconfirmed.append(u)
    return out


@dataclass(slots=True)
class UtmInbox:
    """The UAS' end of the link: the newest directive and the link mode. ``own`` is the id the
    UAS uses for itself in its cases; ``lost_after`` [s] without a directive = link lost."""

    own: str
    lost_after: float
    latest: Directive | None = None
    received_t: float | None = None  # sim time the newest directive arrived [s]
    mode: LinkMode = LinkMode.BLIND
    mandates: dict[str, Mandate] = field(default_factory=dict)  # every mandate received, by id (newest)

    def receive(self, d: Directive, t: float) -> dict:
        """Take a directive that arrived at ``t`` [s] (an older frame than the newest is only
        acknowledged; its mandates are taken either way); returns the acknowledgement: frame, arrival time and
        the ids of the mandates in force."""
        if self.latest is None or d.frame > self.latest.frame:
            cases = tuple(renamed(c, d.to, self.own) for c in d.cases)
            self.latest, self.received_t = replace(d, cases=cases), t
        self.mandates.update((m.id, m) for m in d.mandates)
        return {"frame": d.frame, "received_t": t, "mandates": [m.id for m in self.in_force(t)]}

    def update(self, t: float, peers_heard: bool = False) -> LinkMode | None:
        """The link mode at ``t`` [s] (``peers_heard``: a peer was heard over the
        vehicle-to-vehicle link within ``lost_after``); the new mode when it changed, else None."""
        up = self.received_t is not None and t - self.received_t <= self.lost_after
        mode = LinkMode.COOPERATIVE if up else LinkMode.RESPONSE if peers_heard else LinkMode.BLIND
        if mode == self.mode:
            return None
        self.mode = mode
        return mode

    def cases(self) -> list[CollisionCase]:
        """The UTM cases to merge (none while the link is lost)."""
        if self.mode != LinkMode.COOPERATIVE or self.latest is None:
            return []
        return list(self.latest.cases)

    def in_force(self, t: float) -> list[Mandate]:
        """The mandates binding at ``t`` [s], in id order (whatever the link mode)."""
        return [m for _, m in sorted(self.mandates.items()) if m.active(t)]

    def weather(self) -> list[WeatherCase]:
        """The newest directive's weather cases, in blind mode too (cells move slowly and the
        cases carry their velocity: the last weather picture beats none)."""
        return [] if self.latest is None else list(self.latest.weather)
