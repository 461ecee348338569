"""The UTM part of *Detect collision cases* (tab. 6.10): the UAS' own cases merged with the
central UTM's (:func:`avoidance.utm.directives.merge_cases`), each merge decision an event
``rule:utm_<what>:<own>-<peer>:<encounter>:<role>`` of the frame:

- ``utm_case``: a UTM case obeyed (the UTM's point, encounter and roles, the larger margin);
- ``utm_moved``: the UTM's collision point differs from the own one by the case margin or more
  (reported, the UTM's is used);
- ``utm_unconfirmed``: a UTM-only case about a peer the own surveillance does not track,
  ignored until confirmed (anti-spoofing);
- ``utm_own_only``: an own case the UTM does not have (kept, reported).
Frames and units: GCF (ENU) [m].
"""

from __future__ import annotations

from avoidance.rules.engine import RuleContext
from avoidance.utm.collision_case import CollisionCase
from avoidance.utm.directives import merge_cases


def merge_utm(ctx: RuleContext, own: list[CollisionCase]) -> list[CollisionCase]:
    """The cases to resolve this frame: ``own`` merged with the UTM's when the link is up."""
    if ctx.utm is None:
        return own
    confirmed = {n.id for n in ctx.notifications if n.id != ctx.uas}
    m = merge_cases(own, ctx.utm.cases(), ctx.uas, confirmed)
    for what, cases in (("case", m.utm), ("moved", m.moved), ("unconfirmed", m.unconfirmed)):
        for c in cases:
            ctx.record(f"utm_{what}", c)
    if ctx.utm.latest is not None and ctx.utm.cases():
        for c in m.own_only:
            ctx.record("utm_own_only", c)
    return m.cases
