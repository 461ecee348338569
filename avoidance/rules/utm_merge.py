"""The UTM part of *Detect collision cases* (tab. 6.10): the UAS' own cases merged with the
agreements of response mode (:mod:`avoidance.utm.response`) and then with the central UTM's
(:func:`avoidance.utm.directives.merge_cases` both times: the agreed / directed point, encounter
and roles, the larger margin), each decision an event
``rule:<what>:<own>-<peer>:<encounter>:<role>`` of the frame:

- ``utm_case``: a UTM case obeyed;
- ``utm_moved``: the UTM's collision point differs from the own one by the case margin or more
  (reported, the UTM's is used);
- ``utm_unconfirmed``: a UTM-only case about a peer the own surveillance does not track,
  ignored until confirmed (anti-spoofing);
- ``utm_own_only``: an own case the UTM does not have (kept, reported);
- ``peer_claim``: with the UTM link lost, an own case claimed to its peer (sent);
- ``peer_ack``: a peer's claim acknowledged since the last frame (the role the UAS now holds);
- ``peer_agreed``: an agreed case flown (claimed by one UAS, acknowledged by the other);
- ``peer_unconfirmed``: an agreed case about a peer the own surveillance does not track.
Frames and units: GCF (ENU) [m].
"""

from __future__ import annotations

from avoidance.rules.engine import RuleContext
from avoidance.utm.collision_case import CollisionCase
from avoidance.utm.directives import LinkMode, merge_cases


def merge_utm(ctx: RuleContext, own: list[CollisionCase]) -> list[CollisionCase]:
    """The cases to resolve this frame: ``own`` merged with the peer agreements and with the
    UTM's directed cases while its link is up (the UTM's win where both have the pair)."""
    if ctx.utm is None:
        return own
    confirmed = {n.id for n in ctx.notifications if n.id != ctx.uas}
    cases = own
    if ctx.peers is not None:
        if ctx.utm.mode != LinkMode.COOPERATIVE:
            for c in ctx.peers.claim(ctx.t, own):
                ctx.record("peer_claim", c)
        for c in ctx.peers.drain_acked():
            ctx.record("peer_ack", c)
        p = merge_cases(own, ctx.peers.agreements(ctx.t), ctx.uas, confirmed)
        for what, found in (("agreed", p.utm), ("unconfirmed", p.unconfirmed)):
            for c in found:
                ctx.record(f"peer_{what}", c)
        cases = p.cases
    m = merge_cases(cases, ctx.utm.cases(), ctx.uas, confirmed)
    for what, found in (("case", m.utm), ("moved", m.moved), ("unconfirmed", m.unconfirmed)):
        for c in found:
            ctx.record(f"utm_{what}", c)
    if ctx.utm.latest is not None and ctx.utm.cases():
        for c in m.own_only:
            ctx.record("utm_own_only", c)
    return m.cases
