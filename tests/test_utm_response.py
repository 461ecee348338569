"""Response mode and mandates, vehicle side (avoidance/utm/response.py, avoidance/utm/mandate.py,
avoidance/utm/directives.py): who gives way is agreed by an acknowledged claim, not assumed;
mandates bind from receipt to their end, across a lost link."""

import dataclasses
import math

import numpy as np
import pytest
import shapely

from avoidance.rules.config import RulesConfig
from avoidance.rules.engine import RuleContext
from avoidance.rules.utm_merge import merge_utm
from avoidance.utm.cases import CaseBook
from avoidance.utm.collision_case import CollisionCase, Encounter, Role
from avoidance.utm.directives import Directive, LinkMode, UtmInbox
from avoidance.utm.mandate import Mandate
from avoidance.utm.notification import PositionNotification, Registration
from avoidance.utm.response import PeerMessage, PeerTalk

GIVE, HOLD = Role.CONVERGING, Role.RIGHT_OF_WAY
LOST_AFTER = 3.0


def case(own_role: Role, peer_role: Role, peer: str, head: float = 10.0) -> CollisionCase:
    """An own case (the own UAS is ``self``) with ``peer``."""
    return CollisionCase(
        head,
        ("self", peer),
        Encounter.CONVERGING,
        90.0,
        (own_role, peer_role),
        np.zeros(3),
        0.0,
        5.0,
        40.0,
        True,
        head=head,
    )


def exchange(a: PeerTalk, b: PeerTalk, t: float, lose: frozenset[str] | set[str] = frozenset()) -> None:
    """Deliver everything ``a`` and ``b`` have to send at ``t`` [s], replies included, until
    both are quiet; messages of the kinds in ``lose`` are lost."""
    talks = {a.name: a, b.name: b}
    pending = a.drain() + b.drain()
    while pending:
        m = pending.pop(0)
        if m.kind in lose or m.to is None:
            continue
        talks[m.to].receive(m, t)
        pending += talks[m.to].drain()


def roles(talk: PeerTalk, t: float) -> dict[str, Role]:
    (c,) = talk.agreements(t)
    return {talk.name: c.role_of("self"), c.other("self"): c.role_of(c.other("self"))}


def test_both_in_doubt_the_acknowledged_claim_leaves_one_giving_way():
    """Each UAS' own book gives way (in doubt); uas1 claims its case first, uas2 acknowledges it
    and from then holds uas1's roles: uas1 gives way, uas2 has the right of way."""
    u1, u2 = PeerTalk("uas1", "self", LOST_AFTER), PeerTalk("uas2", "self", LOST_AFTER)
    u1.claim(10.0, [case(GIVE, HOLD, "uas2")])
    assert u1.agreements(10.0) == []  # not acknowledged yet: nothing agreed
    exchange(u1, u2, 10.2)
    assert roles(u1, 10.2) == roles(u2, 10.2) == {"uas1": GIVE, "uas2": HOLD}
    # uas2's own book (also giving way) no longer claims: it acknowledged uas1's claim
    assert u2.claim(11.0, [case(GIVE, GIVE, "uas1")]) == []
    assert u2.drain_acked()[0].role_of("self") == HOLD


def test_simultaneous_claims_the_first_registration_id_stands():
    """Both claim in the same frame with roles that disagree (each says the other gives way):
    uas2 withdraws its claim and acknowledges uas1's; uas1 ignores uas2's claim."""
    u1, u2 = PeerTalk("uas1", "self", LOST_AFTER), PeerTalk("uas2", "self", LOST_AFTER)
    u1.claim(10.0, [case(HOLD, GIVE, "uas2")])
    u2.claim(10.0, [case(HOLD, GIVE, "uas1")])
    exchange(u1, u2, 10.2)
    assert roles(u1, 10.2) == roles(u2, 10.2) == {"uas1": HOLD, "uas2": GIVE}
    assert "uas1" not in u2.claims


def test_an_unacknowledged_claim_agrees_nothing_and_an_agreement_lapses_without_refresh():
    u1, u2 = PeerTalk("uas1", "self", LOST_AFTER), PeerTalk("uas2", "self", LOST_AFTER)
    u1.claim(10.0, [case(GIVE, HOLD, "uas2")])
    exchange(u1, u2, 10.2, lose={"ack"})
    assert u1.agreements(10.2) == [] and len(u2.agreements(10.2)) == 1  # the acknowledger holds it
    u1.claim(11.0, [case(GIVE, HOLD, "uas2")])
    exchange(u1, u2, 11.2)
    assert len(u1.agreements(11.2)) == 1
    assert u1.agreements(11.2 + LOST_AFTER + 0.1) == [] and u2.agreements(11.2 + LOST_AFTER + 0.1) == []
    assert u1.heard(11.2 + LOST_AFTER) and not u1.heard(11.2 + LOST_AFTER + 0.1)


def test_the_claimer_ends_its_agreement_when_its_case_closes():
    u1, u2 = PeerTalk("uas1", "self", LOST_AFTER), PeerTalk("uas2", "self", LOST_AFTER)
    u1.claim(10.0, [case(GIVE, HOLD, "uas2")])
    exchange(u1, u2, 10.2)
    assert u1.claim(11.0, []) == [] and u1.agreements(11.0) == [] and u1.claims == {}


def test_a_closed_encounter_is_not_agreed_again_by_the_later_book():
    """The books close a pair's case a few frames apart (S9 in response mode: uas1 at 39 s,
    uas2 at 43 s). The acknowledger's agreement ends with its own close; the claim its peer sends
    for that encounter afterwards (head case opened before the close) is not acknowledged, so it
    flies no manoeuvre for a finished encounter. A new encounter (head after the close) is."""
    u1, u2 = PeerTalk("uas1", "self", LOST_AFTER), PeerTalk("uas2", "self", LOST_AFTER)
    u2.claim(14.0, [case(HOLD, GIVE, "uas1", head=14.0)])
    exchange(u1, u2, 14.2)
    assert len(u1.agreements(14.2)) == 1 and len(u1.drain_acked()) == 1
    u1.case_closed("uas2", 39.0)
    assert u1.agreements(39.0) == []
    u2.claim(42.0, [case(HOLD, GIVE, "uas1", head=14.0)])
    exchange(u1, u2, 42.2)
    assert u1.agreements(42.2) == [] and u2.agreements(42.2) == [] and u1.drain_acked() == []
    u2.claim(60.0, [case(HOLD, GIVE, "uas1", head=60.0)])
    exchange(u1, u2, 60.2)
    assert roles(u1, 60.2) == roles(u2, 60.2) == {"uas1": GIVE, "uas2": HOLD}


def test_an_acknowledgement_of_another_separation_mode_agrees_nothing():
    u1 = PeerTalk("uas1", "self", LOST_AFTER)
    u1.claim(10.0, [case(GIVE, HOLD, "uas2")])
    (claim,) = u1.drain()
    assert claim.case is not None
    other = dataclasses.replace(claim.case, roles=(HOLD, GIVE))
    u1.receive(PeerMessage("ack", "uas2", "uas1", 10.1, other), 10.2)
    assert u1.agreements(10.2) == [] and u1.heard(10.2)


@pytest.mark.parametrize(
    ("directive_t", "heard", "mode"),
    [(9.0, False, LinkMode.COOPERATIVE), (5.0, True, LinkMode.RESPONSE), (5.0, False, LinkMode.BLIND)],
)
def test_link_mode_cooperative_response_blind(directive_t, heard, mode):
    inbox = UtmInbox("self", LOST_AFTER)
    inbox.receive(Directive(1, directive_t, "uas1"), directive_t)
    inbox.update(10.0, heard)
    assert inbox.mode == mode


def test_mandates_bind_from_receipt_to_their_end_across_a_lost_link_and_are_acknowledged():
    m = Mandate("clear1", 5.0, 30.0, np.array([100.0, 40.0]), 25.0)
    inbox = UtmInbox("self", LOST_AFTER)
    ack = inbox.receive(Directive(6, 6.0, "uas2", mandates=(m,)), 6.2)
    assert ack["mandates"] == ["clear1"]
    inbox.update(20.0)  # no directive since 6.2 s: lost
    assert inbox.mode == LinkMode.BLIND and inbox.cases() == [] and inbox.in_force(20.0) == [m]
    assert inbox.in_force(30.0) == []
    assert Mandate.from_record(m.record()).record() == m.record()
    fence = m.geofence()
    assert not fence.keep_in and fence.area.contains(shapely.Point(40.0, 100.0 + 24.0))
    assert m.inside(np.array([100.0, 40.0 + 24.0, 20.0])) and not m.inside(np.array([100.0, 40.0 + 26.0, 20.0]))
    assert math.isinf(fence.up_max_m)


def _ctx(inbox: UtmInbox, talk: PeerTalk, t: float) -> RuleContext:
    notes = [
        PositionNotification(t, Registration(who), np.zeros(3), np.array([5.0, 0.0, 0.0])) for who in ("self", "uas1")
    ]
    return RuleContext("self", t, RulesConfig(), CaseBook(), notes, 5.0, 1.0, utm=inbox, peers=talk)


def test_a_directed_uas_acknowledges_a_lost_peer_and_flies_the_agreement_unless_the_utm_has_the_pair():
    """uas2 under the authority (directives arrive, none about uas1, whom the authority has
    lost): uas1's acknowledged claim is flown over uas2's own case, and uas2 claims nothing
    itself; a UTM case about the pair wins over the agreement."""
    inbox, talk = UtmInbox("self", LOST_AFTER), PeerTalk("uas2", "self", LOST_AFTER)
    inbox.receive(Directive(10, 10.0, "uas2"), 10.0)
    inbox.update(10.5)
    claim = case(GIVE, HOLD, "uas2")  # uas1's case: uas1 gives way
    talk.receive(PeerMessage("claim", "uas1", "uas2", 10.3, dataclasses.replace(claim, ids=("uas1", "uas2"))), 10.5)
    own = [case(GIVE, GIVE, "uas1")]  # uas2's own book: in doubt, gives way
    ctx = _ctx(inbox, talk, 10.5)
    (flown,) = merge_utm(ctx, own)
    assert flown.role_of("self") == HOLD and flown.role_of("uas1") == GIVE
    assert "rule:peer_agreed:self-uas1:converging:right_of_way" in ctx.events
    assert not any(e.startswith("rule:peer_claim") for e in ctx.events)
    directed = case(Role.ROUNDABOUT, Role.ROUNDABOUT, "uas1")
    inbox.receive(Directive(11, 11.0, "uas2", (dataclasses.replace(directed, ids=("uas2", "uas1")),)), 11.0)
    (flown,) = merge_utm(_ctx(inbox, talk, 11.2), own)
    assert flown.role_of("self") == Role.ROUNDABOUT
