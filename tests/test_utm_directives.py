"""Vehicle side of the central UTM (avoidance/utm/directives.py, avoidance/rules/utm_merge.py):
the merge of UTM cases with the own ones (tab. 6.10, anti-spoofing) and the link mode."""

import numpy as np

from avoidance.utm.collision_case import CollisionCase, Encounter, Role
from avoidance.utm.directives import Directive, LinkMode, UtmInbox, merge_cases


def case(ids, roles, cp=(0.0, 0.0, 0.0), margin=40.0, encounter=Encounter.CONVERGING) -> CollisionCase:
    return CollisionCase(0.0, ids, encounter, 90.0, roles, np.array(cp, float), 0.0, 5.0, margin, True, head=0.0)


def test_both_cases_take_the_utm_roles_and_point_and_the_larger_margin():
    own = case(("self", "b"), (Role.RIGHT_OF_WAY, Role.CONVERGING), cp=(0.0, 0.0, 0.0), margin=40.0)
    utm = case(("b", "self"), (Role.RIGHT_OF_WAY, Role.CONVERGING), cp=(50.0, 0.0, 0.0), margin=30.0)
    m = merge_cases([own], [utm], "self", {"b"})
    (c,) = m.cases
    assert c.role_of("self") == Role.CONVERGING and c.role_of("b") == Role.RIGHT_OF_WAY  # UTM's, by id
    assert np.allclose(c.collision_point, [50.0, 0.0, 0.0]) and c.margin == 40.0
    assert m.moved == [c]  # 50 m apart >= the 40 m margin: reported
    near = case(("b", "self"), (Role.RIGHT_OF_WAY, Role.CONVERGING), cp=(39.0, 0.0, 0.0), margin=30.0)
    assert merge_cases([own], [near], "self", {"b"}).moved == []


def test_a_utm_only_case_is_obeyed_only_once_the_own_surveillance_confirms_the_peer():
    forged = case(("self", "ghost"), (Role.ROUNDABOUT, Role.ROUNDABOUT), encounter=Encounter.HEAD_ON)
    m = merge_cases([], [forged], "self", {"b"})
    assert m.cases == [] and m.unconfirmed == [forged]
    m = merge_cases([], [forged], "self", {"b", "ghost"})
    assert m.cases == [forged] and m.utm == [forged] and m.unconfirmed == []


def test_an_own_case_the_utm_lacks_is_kept_and_reported():
    own = case(("self", "b"), (Role.CONVERGING, Role.RIGHT_OF_WAY))
    m = merge_cases([own], [], "self", {"b"})
    assert m.cases == [own] and m.own_only == [own]


def test_inbox_renames_the_recipient_acknowledges_and_loses_the_link_after_lost_after():
    box = UtmInbox("self", lost_after=3.0)
    assert box.update(0.0) is None and box.mode == LinkMode.BLIND  # nothing received yet
    d = Directive(4, 4.0, "uas1", (case(("uas1", "uas2"), (Role.CONVERGING, Role.RIGHT_OF_WAY)),))
    assert box.receive(d, 4.2) == {"frame": 4, "received_t": 4.2, "mandates": []}
    assert box.update(4.2) == LinkMode.COOPERATIVE
    assert box.cases()[0].ids == ("self", "uas2") and box.cases()[0].role_of("self") == Role.CONVERGING
    box.receive(Directive(3, 3.0, "uas1"), 4.3)  # an older frame arriving late: acknowledged, not taken
    assert box.latest is not None and box.latest.frame == 4
    assert box.update(7.2) is None  # exactly lost_after: still up
    assert box.update(7.3) == LinkMode.BLIND and box.cases() == []
    box.receive(Directive(8, 8.0, "uas1"), 8.0)
    assert box.update(8.0) == LinkMode.COOPERATIVE
