"""Response mode (spec §7.1, seed 000 §6.8.3, fig. 6.30): when the central UTM is out of touch,
UAS that still hear each other over their vehicle-to-vehicle link agree who gives way by
acknowledged messages instead of each assuming it.

The exchange of the spec's example, per pair:
1. every UAS broadcasts its position notification to its peers (``notification``);
2. a UAS whose UTM link is lost computes its collision cases (its own case book) and sends each
   peer of an active case a *claim*: the case as it resolves it (encounter = separation mode,
   collision point, margin, both roles);
3. the peer *acknowledges* the claim (``ack``) and from then on flies the claimed case;
4. the claimer flies it once the acknowledgement has arrived: both hold the same roles
   (consensus). Before that, and when no acknowledgement comes, each flies its own case.
Who claims: whoever claims first; when both claim at once, the claim of the UAS whose
registration id sorts first stands (the other withdraws its own and acknowledges), so exactly
one claim per pair is acknowledged. The claimer re-sends its claim every frame while its case
is active and the peer acknowledges each: an agreement lapses ``lost_after`` [s] after its last
claim (acknowledger) or acknowledgement (claimer), and at once on the claimer's side when its
case closes. A claim for an encounter the UAS' own book has closed (its head case opened before
the close) is not acknowledged, and closing its case ends the UAS' agreement with that peer: the
two books close a pair's case a few frames apart, and the later one's claim must not re-open the
encounter on the other. A UAS that has heard no peer for ``lost_after`` flies *blind* (rules of the air on
its own cases).
Messages carry registration ids; the UAS' own cases name it ``own``. Frames: GCF (ENU) [m],
sim seconds [s].
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from avoidance.utm.collision_case import CollisionCase


@dataclass(frozen=True, slots=True)
class PeerMessage:
    """One message on the vehicle-to-vehicle link: ``notification`` (broadcast, ``to`` None;
    position and velocity GCF), ``claim`` or ``ack`` (the claimed case, registration ids)."""

    kind: str
    sender: str
    to: str | None
    t: float  # sent [s]
    case: CollisionCase | None = None
    pos: np.ndarray | None = None  # [m]
    vel: np.ndarray | None = None  # [m/s]


@dataclass(frozen=True, slots=True)
class Agreement:
    """A claimed case both UAS hold (own naming), who claimed it, when it was last confirmed [s]."""

    case: CollisionCase
    claimer: str
    t: float


def renamed(c: CollisionCase, old: str, new: str) -> CollisionCase:
    """``c`` with the id ``old`` replaced by ``new``."""
    a, b = (new if i == old else i for i in c.ids)
    return replace(c, ids=(a, b))


def same_claim(a: CollisionCase, b: CollisionCase) -> bool:
    """Whether two claims are the same separation mode: pair, head case, encounter and roles."""
    return a.ids == b.ids and a.head == b.head and a.encounter == b.encounter and a.roles == b.roles


@dataclass(slots=True)
class PeerTalk:
    """A UAS' end of the vehicle-to-vehicle link (module docstring): ``name`` its registration
    id, ``own`` its id in its own cases."""

    name: str
    own: str
    lost_after: float  # [s]
    heard_t: float | None = None  # last message from any peer [s]
    claims: dict[str, CollisionCase] = field(default_factory=dict)  # peer -> the own standing claim
    agreed: dict[str, Agreement] = field(default_factory=dict)  # peer -> agreement
    outbox: list[PeerMessage] = field(default_factory=list)
    acked: list[CollisionCase] = field(default_factory=list)  # claims acknowledged since the last frame (own naming)
    closed: dict[str, float] = field(default_factory=dict)  # peer -> when the own case with it closed [s]

    def heard(self, t: float) -> bool:
        """Whether a peer was heard within ``lost_after`` of ``t`` [s]."""
        return self.heard_t is not None and t - self.heard_t <= self.lost_after

    def receive(self, m: PeerMessage, t: float) -> None:
        """A message arrived at ``t`` [s]."""
        self.heard_t = t
        if m.case is None:
            return
        if m.kind == "claim":
            if m.case.head is not None and m.case.head <= self.closed.get(m.sender, -np.inf):
                return  # an encounter the own book has closed
            mine = self.claims.get(m.sender)
            if mine is not None and self.name < m.sender:
                return  # both claimed: the own claim stands, the peer acknowledges it
            self.claims.pop(m.sender, None)
            case = renamed(m.case, self.name, self.own)
            self.agreed[m.sender] = Agreement(case, m.sender, t)
            self.outbox.append(PeerMessage("ack", self.name, m.sender, t, m.case))
            self.acked.append(case)
        elif m.kind == "ack":
            mine = self.claims.get(m.sender)
            if mine is not None and same_claim(mine, m.case):
                self.agreed[m.sender] = Agreement(renamed(mine, self.name, self.own), self.name, t)

    def case_closed(self, peer: str, t: float) -> None:
        """The own case with ``peer`` closed at frame time ``t`` [s]: the agreement with it
        ends, and its claims for that encounter are no longer acknowledged."""
        self.closed[peer] = t
        self.agreed.pop(peer, None)

    def claim(self, t: float, own: list[CollisionCase]) -> list[CollisionCase]:
        """This frame's claims (sent at ``t`` [s]) for the own active cases ``own`` whose peer
        has no standing agreement on its own claim; the own claims of closed cases end. Returns
        the cases claimed (own naming)."""
        current = {c.other(self.own): c for c in own}
        for peer in [p for p in self.claims if p not in current]:
            del self.claims[peer]
            if peer in self.agreed and self.agreed[peer].claimer == self.name:
                del self.agreed[peer]
        out = []
        for peer, c in sorted(current.items()):
            a = self.agreed.get(peer)
            if a is not None and a.claimer != self.name and t - a.t <= self.lost_after:
                continue  # acknowledged the peer's claim: it stands
            self.claims[peer] = renamed(c, self.own, self.name)
            self.outbox.append(PeerMessage("claim", self.name, peer, t, self.claims[peer]))
            out.append(c)
        return out

    def agreements(self, t: float) -> list[CollisionCase]:
        """The agreed cases in force at ``t`` [s] (own naming)."""
        return [a.case for a in self.agreed.values() if t - a.t <= self.lost_after]

    def drain(self) -> list[PeerMessage]:
        """The messages to send now (emptied)."""
        out, self.outbox = self.outbox, []
        return out

    def drain_acked(self) -> list[CollisionCase]:
        """The claims acknowledged since the last call (emptied)."""
        out, self.acked = self.acked, []
        return out
