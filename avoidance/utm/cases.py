"""Case chaining and the roundabout merge (spec §7.4, A-32), for every pair of UAS a virtual
UTM knows (each cooperative UAS runs one over all notifications it receives, so all of them
derive the same cases from the same traffic picture).

Chaining: a pair flagged with the same encounter in two consecutive frames opens a chain whose
*head* is the second of them (one frame of confirmation: a single flag from a fresh or noisy
track does not fix the roles); the head fixes collision point, encounter, roles and margin for
the whole manoeuvre, later frames only update distance, time to the
closest approach and separation. The chain closes (its *tail*) after ``close_after`` frames in
which the pair is past its closest approach, at least the head's margin apart and both heading
away from the head's collision point (spec §7.2) and, for an overtake, the overtaking UAS is the
margin ahead of the overtaken (:func:`overtaken`), or the peer is no longer reported. (Closing
as soon as the pair diverged let a 4-UAS roundabout cut back across its centre and meet again.)
A UAS that hovers (below half the hover gate ``min_speed``) has no heading: it counts as heading
away and an overtake with it is over, so with one UAS hovering the chain closes once the other
is past its closest approach to it, the margin apart and heading away; with both hovering, once
they are the margin apart. A pair with an open chain stays assessed at any speed, one awaiting
its confirming frame down to half the hover gate (``gate`` of :func:`compute_collision_case`):
the tracked speed of a slow UAS fluctuates across the gate, a pair dropped for two frames ended
its chain mid-overtake and re-opened it with the geometry of that moment, and a give-way UAS
that hovered out its soft deadlock ended its case and met the peer again as a fresh head-on
case already inside the margin.
Merge: the active head-on and converging chains that share a UAS form a cluster (overtakes are
not merged: several at once slow the overtaking UAS, 6.202); a cluster of two or more chains is a
virtual roundabout with centre = mean of the head collision points (weights 1, 6.195) and margin
= the largest margin of its cases (6.196); every member then circles it (role roundabout).
Frames/units: GCF (ENU) [m], sim seconds [s].
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from avoidance.utm.collision_case import CollisionCase, Encounter, Role, UtmConfig, compute_collision_case
from avoidance.utm.notification import PositionNotification

HOVERS = 0.5  # a UAS slower than this share of the hover gate ``min_speed`` hovers for good


@dataclass(slots=True)
class Chain:
    head: CollisionCase
    last: CollisionCase
    quiet: int = 0  # consecutive frames past the closest approach / without a report

    @property
    def case(self) -> CollisionCase:
        """The current case with the head's point, encounter, roles and margin (chaining)."""
        h = self.head
        return replace(
            self.last,
            encounter=h.encounter,
            alpha_deg=h.alpha_deg,
            roles=h.roles,
            collision_point=h.collision_point,
            margin=h.margin,
            head=h.t,
        )


@dataclass(frozen=True, slots=True)
class Roundabout:
    members: frozenset[str]
    centre: np.ndarray  # GCF [m]
    margin: float  # [m]


@dataclass(slots=True)
class SharedHeads:
    """The open chains' head cases of several books that must agree (the authorities of one
    airspace, one per cluster): per pair, the head and the books holding it."""

    heads: dict[tuple[str, str], tuple[CollisionCase, set[int]]] = field(default_factory=dict)

    def hold(self, key: tuple[str, str], head: CollisionCase, book: int) -> CollisionCase:
        """The pair's head: the one already held (``book`` joins it), else ``head``."""
        held, books = self.heads.setdefault(key, (head, set()))
        books.add(book)
        return held

    def release(self, key: tuple[str, str], book: int) -> None:
        entry = self.heads.get(key)
        if entry is not None:
            entry[1].discard(book)
            if not entry[1]:
                del self.heads[key]


@dataclass(slots=True)
class CaseBook:
    """Active collision-case chains keyed by the sorted pair of ids. With ``shared``, a pair whose
    chain another book holds open is opened here at once with that book's head (collision point,
    encounter, roles, margin, head time) as soon as the pair is assessed, so books over the same
    traffic agree whatever notifications each of them lost."""

    cfg: UtmConfig = field(default_factory=UtmConfig)
    chains: dict[tuple[str, str], Chain] = field(default_factory=dict)
    shared: SharedHeads | None = None

    assessed: set[tuple[str, str]] = field(default_factory=set)  # pairs with a case computed this frame
    pending: dict[tuple[str, str], CollisionCase] = field(default_factory=dict)  # flagged once, not yet opened

    def update(
        self, notifications: list[PositionNotification], t: float
    ) -> tuple[list[CollisionCase], list[CollisionCase]]:
        """Compute every pair's case at frame time ``t`` [s], chain them; returns the cases
        opened and closed in this frame (:attr:`assessed` holds the pairs computed)."""
        opened = self.assess(notifications, t)
        return opened, self.close(self.due())

    def assess(self, notifications: list[PositionNotification], t: float) -> list[CollisionCase]:
        """The first half of :meth:`update`: every pair's case at ``t`` [s] chained and each
        chain's count of quiet frames updated, nothing closed; returns the cases opened."""
        opened = []
        seen = self.assessed = set()
        last_pending, self.pending = self.pending, {}
        notes = sorted(notifications, key=lambda n: n.id)
        for i, a in enumerate(notes):
            for b in notes[i + 1 :]:
                key = (a.id, b.id)
                gate = 0.0 if key in self.chains else HOVERS if key in last_pending else 1.0
                case = compute_collision_case(a, b, t, self.cfg, gate)
                if case is None:
                    continue
                seen.add(key)
                chain = self.chains.get(key)
                if chain is None:
                    seen_before = last_pending.get(key)
                    held = self.shared is not None and key in self.shared.heads
                    if held or (case.flagged and seen_before is not None and seen_before.encounter == case.encounter):
                        case.head = t
                        head = case if self.shared is None else self.shared.hold(key, case, id(self))
                        self.chains[key] = Chain(replace(head, links=[]), case)
                        opened.append(self.chains[key].case)
                    if case.flagged and key not in self.chains:
                        self.pending[key] = case
                    continue
                chain.head.links.append(t)
                chain.last = case
                cp = chain.head.collision_point
                moving = [n for n in (a, b) if n.speed >= HOVERS * self.cfg.min_speed]
                clear = (
                    case.separation >= chain.head.margin
                    and (case.t_cpa <= 0.0 or not moving)
                    and all(float((n.pos + n.vel * (t - n.t) - cp) @ n.vel) > 0.0 for n in moving)
                    and (len(moving) < 2 or overtaken(chain.head, a, b, t))
                )
                chain.quiet = chain.quiet + 1 if clear else 0
        for key in [k for k in self.chains if k not in seen]:
            self.chains[key].quiet += 1
        return opened

    def due(self) -> set[tuple[str, str]]:
        """The pairs whose chains have been quiet for ``close_after`` frames."""
        return {k for k, c in self.chains.items() if c.quiet >= self.cfg.close_after}

    def close(self, keys: set[tuple[str, str]]) -> list[CollisionCase]:
        """Close the chains of ``keys`` this book holds (their tails); returns their cases."""
        closed = []
        for key in [k for k in self.chains if k in keys]:
            closed.append(self.chains.pop(key).case)
            if self.shared is not None:
                self.shared.release(key, id(self))
        return closed

    def active(self, uas: str | None = None) -> list[CollisionCase]:
        """Active cases (of ``uas`` if given), head-chained."""
        return [c.case for k, c in sorted(self.chains.items()) if uas is None or uas in k]

    def roundabouts(self) -> list[Roundabout]:
        """Clusters of two or more active head-on / converging cases sharing a UAS, as virtual
        roundabouts. Overtakes stay apart: they are resolved by their divergence / convergence
        waypoints and, several at once, by the speed change (6.202)."""
        cases = [c for c in self.active() if c.encounter != Encounter.OVERTAKE]
        parent: dict[str, str] = {}

        def find(x: str) -> str:
            while parent.setdefault(x, x) != x:
                x = parent[x]
            return x

        for c in cases:
            parent[find(c.ids[0])] = find(c.ids[1])
        groups: dict[str, list[CollisionCase]] = {}
        for c in cases:
            groups.setdefault(find(c.ids[0]), []).append(c)
        return [
            Roundabout(
                frozenset(u for c in g for u in c.ids),
                np.mean([c.collision_point for c in g], axis=0),
                max(c.margin for c in g),
            )
            for _, g in sorted(groups.items())
            if len(g) >= 2
        ]


def closing_together(books: list[CaseBook]) -> set[tuple[str, str]]:
    """The pairs that close this frame in ``books`` that must agree (the authorities of one
    airspace, after each has run :meth:`CaseBook.assess`): those quiet for ``close_after`` frames
    in every book holding them. Each of those books then closes them in the same frame; one book
    closing alone would leave its roundabouts without the case while the others still hold it."""
    due = [(b.chains, b.due()) for b in books]
    held = set().union(*(chains for chains, _ in due))
    return {k for k in held if all(k in d for chains, d in due if k in chains)}


def overtaken(head: CollisionCase, a: PositionNotification, b: PositionNotification, t: float) -> bool:
    """Whether an overtake is over (always true for other encounters): the one overtaking UAS is
    at least the head's margin ahead of the overtaken along the latter's course at ``t`` [s]
    (tab. 6.15: the parallel offset is held until then; closing at abeam let the overtaking UAS cut
    back 10-15 m ahead of the overtaken, S12 seed 10: 21.5 m against 25 m)."""
    if head.encounter != Encounter.OVERTAKE or head.roles.count(Role.OVERTAKING) != 1:
        return True
    fast, slow = (a, b) if head.role_of(a.id) == Role.OVERTAKING else (b, a)
    course = slow.vel[:2] / max(float(np.linalg.norm(slow.vel[:2])), 1e-9)
    ahead = float((fast.adjusted(t).pos[:2] - slow.adjusted(t).pos[:2]) @ course)
    return ahead >= head.margin


def as_roundabout(case: CollisionCase, rb: Roundabout) -> CollisionCase:
    """A member's case re-targeted at its roundabout: centre, margin, both roles roundabout."""
    return replace(case, collision_point=rb.centre, margin=rb.margin, roles=(Role.ROUNDABOUT, Role.ROUNDABOUT))
