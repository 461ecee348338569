"""UTM collision cases and the rules' restrictions, open loop (spec §7.4/§7.7; unit vectors
T-UT-1..6 of §9.2) with hypothesis properties of the classification and of symmetric encounters."""

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from avoidance.reachset.cache import reach_set
from avoidance.reachset.config import AvoidanceConfig, MovementConfig
from avoidance.reachset.frames import GridPose
from avoidance.reachset.fusion import Categories, ThreatParts, fuse
from avoidance.reachset.grid import AvoidanceGrid
from avoidance.reachset.gridrun import find_best_path
from avoidance.reachset.movement import build_primitive_table
from avoidance.rules.config import RulesConfig
from avoidance.rules.restrictions import (
    moving_margin_mask,
    path_clearance,
    right_plane_heading_mask,
    safety_margin_mask,
    widest_per_cell,
)
from avoidance.rules.rules_of_air import overtake_speed, overtake_waypoints, pass_behind_point
from avoidance.utm.cases import CaseBook, SharedHeads, closing_together
from avoidance.utm.collision_case import (
    GIVES_WAY,
    Encounter,
    Role,
    UtmConfig,
    angle_of_approach,
    case_margin,
    classify,
    closest_approach,
    collision_margin,
    compute_collision_case,
    trajectory_min_distance,
)
from avoidance.utm.notification import (
    Category,
    Maneuverability,
    Margins,
    PositionNotification,
    Registration,
    flight_levels,
)
from sim.core.constants import FT
from sim.scenario import ScenarioError, load_scenario

CFG = RulesConfig().avoidance(AvoidanceConfig())
GRID = AvoidanceGrid(CFG.grid)
NAV = reach_set(GRID, build_primitive_table(MovementConfig()), CFG.navigation)  # thesis ACAS-like horizontal tree


def note(uas, pos, vel, t=0.0, **reg) -> PositionNotification:
    return PositionNotification(t, Registration(uas, **reg), np.asarray(pos, float), np.asarray(vel, float))


# -- T-UT-1..6 -------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "alpha, speeds, expected",
    [
        (180.0, (1, 1), Encounter.HEAD_ON),
        (130.0, (1, 1), Encounter.HEAD_ON),
        (129.9, (1, 1), Encounter.CONVERGING),
        (70.0, (1, 1), Encounter.CONVERGING),
        (69.9, (2, 1), Encounter.OVERTAKE),
        (69.9, (1, 1), Encounter.CONVERGING),
        (10.0, (1, 1.2), Encounter.CONVERGING),
        (10.0, (1, 1.21), Encounter.OVERTAKE),
    ],
)
def test_ut1_classification_thresholds(alpha, speeds, expected):
    assert classify(alpha, *speeds) == expected


SCALED = UtmConfig(time_margin=25.0, speed_tolerance=1.0, speed_doubt=0.5)  # rules_unit = 5 (RulesConfig.utm)


def _meeting(alpha_deg: float, speeds: tuple[float, float], t_meet: float = 12.0):
    """Two UAS flying straight at the origin, arriving together after ``t_meet`` s: UAS a from
    the west flying east, UAS b on a course ``alpha_deg`` turned left of a's reversed course.
    Returns (pos, vel) of a and b, GCF ENU [m], [m/s]."""
    da = np.array([-1.0, 0.0, 0.0])  # from the meeting point towards a
    t = np.radians(alpha_deg)
    db = np.array([-np.cos(t), -np.sin(t), 0.0])  # α measured from da, counter-clockwise
    return (speeds[0] * t_meet * da, -speeds[0] * da), (speeds[1] * t_meet * db, -speeds[1] * db)


@pytest.mark.parametrize(
    "alpha, speeds, encounter, roles",  # at the scenarios' scale: speed tolerance 1 m/s, doubt 0.5 m/s
    [
        # opposite courses: head-on, both circle right
        (180.0, (5, 5), Encounter.HEAD_ON, (Role.ROUNDABOUT, Role.ROUNDABOUT)),
        # b from the south flying north: b is on east-bound a's right, a gives way (S9)
        (90.0, (5, 5), Encounter.CONVERGING, (Role.CONVERGING, Role.RIGHT_OF_WAY)),
        # courses 60° apart at equal speeds (the campaign's encounter 7): they close abeam at
        # 2·5·sin 30° = 5 m/s; b (south-west of a, flying north-east) is on a's right: a gives way
        (60.0, (5, 5), Encounter.CONVERGING, (Role.CONVERGING, Role.RIGHT_OF_WAY)),
        # b from the north-west: on a's left, b gives way
        (-60.0, (5, 5), Encounter.CONVERGING, (Role.RIGHT_OF_WAY, Role.CONVERGING)),
        # 20° apart, b at 2.5 m/s: a is faster and overtakes
        (20.0, (5, 2.5), Encounter.OVERTAKE, (Role.OVERTAKING, Role.OVERTAKEN)),
    ],
)
def test_encounter_classes_by_hand(alpha, speeds, encounter, roles):
    """Hand-checkable geometry per class (spec §7.2 thresholds; α < 70° at equal speeds is
    converging, not a class of its own)."""
    (pa, va), (pb, vb) = _meeting(abs(alpha), speeds)
    if alpha < 0:
        pb, vb = pb * [1, -1, 1], vb * [1, -1, 1]
    case = compute_collision_case(note("a", pa, va), note("b", pb, vb), 0.0, SCALED)
    assert case.flagged and case.alpha_deg == pytest.approx(abs(alpha))
    assert case.encounter == encounter and case.roles == roles


def _two_views(rng, alpha, speeds, track_pos=3.0, track_vel=0.2, own_pos=0.5, own_vel=0.05, cfg=SCALED):
    """The pair as each UAS computes it: its own estimate (EKF-like error) and its track of the
    other (surveillance-like error), drawn independently per side (uniform within the bounds);
    returns (role of a in a's case, role of b in b's case) and the truth's case."""
    (pa, va), (pb, vb) = _meeting(alpha, speeds)
    rot = rng.uniform(-np.pi, np.pi)
    r = np.array([[np.cos(rot), -np.sin(rot), 0], [np.sin(rot), np.cos(rot), 0], [0, 0, 1]])
    pa, va, pb, vb = r @ pa, r @ va, r @ pb, r @ vb

    def err(pos_bound, vel_bound):
        e = rng.uniform(-1.0, 1.0, (2, 3)) * [[pos_bound] * 2 + [0.0], [vel_bound] * 2 + [0.0]]
        return e[0], e[1]

    def view(own_p, own_v, peer_p, peer_v, own_id, peer_id):
        (ep, ev), (tp, tv) = err(own_pos, own_vel), err(track_pos, track_vel)
        case = compute_collision_case(
            note(own_id, own_p + ep, own_v + ev), note(peer_id, peer_p + tp, peer_v + tv), 0.0, cfg
        )
        return None if case is None or not case.flagged else case.role_of(own_id)

    truth = compute_collision_case(note("a", pa, va), note("b", pb, vb), 0.0, cfg)
    return view(pa, va, pb, vb, "a", "b"), view(pb, vb, pa, va, "b", "a"), truth


def test_the_two_sides_never_both_hold_course_on_noisy_tracks():
    """Each UAS classifies the pair from its own estimate and its noisy track of the other: over
    random encounters (any α, equal or different speeds, any orientation) the two sides' roles
    are complementary: never do both hold their course (right of way / overtaken); away from the
    thresholds (α more than 2 doubts from 70° / 130°, speed difference more than 2 doubts from the
    tolerance) each side takes exactly the truth's role. With the doubts off (each side trusting
    its estimate: the previous classifier's behaviour) the same draws do leave both holding."""
    rng = np.random.default_rng(17)
    cfg = SCALED
    draws = []
    for _ in range(1500):
        alpha = rng.uniform(1.0, 179.0)
        s1 = rng.uniform(3.0, 6.0)
        s2 = s1 if rng.random() < 0.5 else s1 + rng.uniform(-1.5, 1.5)
        draws.append((alpha, (s1, s2), rng.bit_generator.state))
    both_hold = {True: 0, False: 0}
    for doubt in (True, False):
        c = cfg if doubt else dataclasses.replace(cfg, angle_doubt=0.0, speed_doubt=0.0)
        for alpha, speeds, state in draws:
            rng.bit_generator.state = state
            ra, rb, truth = _two_views(rng, alpha, speeds, cfg=c)
            if ra is None or rb is None:
                continue
            both_hold[doubt] += ra not in GIVES_WAY and rb not in GIVES_WAY
            clear = (
                min(abs(alpha - 70.0), abs(alpha - 130.0)) > 2 * cfg.angle_doubt
                and abs(abs(speeds[0] - speeds[1]) - cfg.speed_tolerance) > 2 * cfg.speed_doubt
            )
            if doubt and clear:
                assert (ra, rb) == truth.roles, (alpha, speeds)
    assert both_hold[True] == 0
    assert both_hold[False] > 0


def test_ut2_head_on_cpa():
    t, d, cp = closest_approach((0, 20, 0), (1, 0, 0), (40, 20, 0), (-1, 0, 0))
    assert t == pytest.approx(20.0) and d == pytest.approx(0.0) and cp == pytest.approx([20, 20, 0])
    assert angle_of_approach((0, 20, 0), (40, 20, 0), cp) == pytest.approx(180.0)
    case = compute_collision_case(
        note("a", (0, 20, 0), (1, 0, 0)), note("b", (40, 20, 0), (-1, 0, 0)), 0.0, UtmConfig(time_margin=25.0)
    )
    assert case.flagged and case.encounter == Encounter.HEAD_ON and case.roles == (Role.ROUNDABOUT, Role.ROUNDABOUT)
    assert case.margin == pytest.approx(10.0)


def test_ut3_converging_cpa_and_right_of_way():
    t, d, cp = closest_approach((0, 20, 0), (1, 0, 0), (20, 0, 0), (0, 1, 0))
    assert t == pytest.approx(20.0) and d == pytest.approx(0.0) and cp == pytest.approx([20, 20, 0])
    assert angle_of_approach((0, 20, 0), (20, 0, 0), cp) == pytest.approx(90.0)
    case = compute_collision_case(
        note("uas1", (0, 20, 0), (1, 0, 0)), note("uas2", (20, 0, 0), (0, 1, 0)), 0.0, UtmConfig(time_margin=25.0)
    )
    # UAS1 (east-bound) has UAS2 on its right: it gives way (S9)
    assert case.encounter == Encounter.CONVERGING and case.roles == (Role.CONVERGING, Role.RIGHT_OF_WAY)
    assert case.margin == pytest.approx(8.0)


def test_ut4_margins_with_reference_defaults():
    m = Margins()
    assert case_margin(Encounter.HEAD_ON, m, m, (Role.ROUNDABOUT, Role.ROUNDABOUT)) == 10.0
    assert case_margin(Encounter.CONVERGING, m, m, (Role.RIGHT_OF_WAY, Role.CONVERGING)) == 8.0
    assert case_margin(Encounter.OVERTAKE, m, m, (Role.OVERTAKING, Role.OVERTAKEN)) == 5.0
    assert collision_margin(m, m) == 16.0
    # the converging branch takes the avoider's converging and the right-of-way UAS' universal margin
    a, b = Margins(universal=9.0), Margins(converging=3.0)
    assert case_margin(Encounter.CONVERGING, a, b, (Role.RIGHT_OF_WAY, Role.CONVERGING)) == 9.0
    assert case_margin(Encounter.CONVERGING, a, b, (Role.CONVERGING, Role.RIGHT_OF_WAY)) == 8.0


def test_ut5_passing_flight_level_within_250_ft():
    step = 1000 * FT
    main, passing = flight_levels(5 * step + 500 * FT)
    assert main == 5 and passing == frozenset()
    assert flight_levels(5 * step + 249 * FT)[1] == {4}
    assert flight_levels(6 * step - 249 * FT)[1] == {6}
    assert flight_levels(5 * step + 500 * FT, climb_rate=2.0)[1] == {6}
    far = note("b", (0, 0, 3 * step), (0, 0, 0))
    assert not note("a", (0, 0, 500 * FT), (0, 0, 0)).shares_level(far)


def test_ut6_speed_reduction():
    assert overtake_speed(1.0, [3.0, 2.0]) == 2.0
    assert overtake_speed(2.5, [3.0, 2.0]) == 2.5


# -- trajectory intersection, overtake, chaining, roundabout --------------------------------------
def test_trajectory_intersection_overrides_the_linear_point():
    t = np.arange(0.0, 21.0)
    # UAS1 turns away after 5 s; the linear prediction would meet head-on at (20, 20)
    p1 = np.stack([t, 20 + np.clip(t - 5, 0, None), 0 * t], axis=1)
    p2 = np.stack([40 - t, 20 + 0 * t, 0 * t], axis=1)
    d, cp, tm = trajectory_min_distance(p1, p2, t)
    assert tm == pytest.approx(np.argmin(np.linalg.norm(p1 - p2, axis=1)))
    assert cp == pytest.approx(0.5 * (p1[int(tm)] + p2[int(tm)]))
    a = PositionNotification(0.0, Registration("a"), p1[0], np.array([1.0, 0, 0]), trajectory=p1, trajectory_t=t)
    b = PositionNotification(0.0, Registration("b"), p2[0], np.array([-1.0, 0, 0]), trajectory=p2, trajectory_t=t)
    case = compute_collision_case(a, b, 0.0, UtmConfig(time_margin=25.0))
    assert case.trajectory and case.distance == pytest.approx(d) and case.distance > 5.0


def test_overtake_roles_and_waypoints_on_the_right():
    fast, slow = note("a", (-40, 20, 0), (2, 0, 0)), note("b", (-20, 20, 0), (1, 0, 0))
    case = compute_collision_case(fast, slow, 0.0, UtmConfig(time_margin=25.0))
    assert case.encounter == Encounter.OVERTAKE and case.roles == (Role.OVERTAKING, Role.OVERTAKEN)
    div, conv = overtake_waypoints(fast.pos, fast.vel, slow.pos, slow.vel, case.collision_point, 5.0, 1.0, 2.0)
    # overtaken heads +x: its right is -y; offset = Δv·frame + margin = 6
    assert div == pytest.approx(case.collision_point + [0, -6, 0])
    assert conv[0] - div[0] == pytest.approx(
        np.sqrt(40.0**2 + 25.0) + 1 + 2
    )  # |p - cp| = 40 (meet at x = 0) and conv[1] == pytest.approx(div[1])


@pytest.mark.parametrize("fast_y", [25.0, 15.0])
def test_overtake_waypoints_are_offset_from_the_overtaken_track_not_from_the_midpoint(fast_y):
    """The collision point is the midpoint at the closest approach: with the overtaking UAS 5 m
    left (y = 25) or right (y = 15) of the overtaken track (y = 20, heading +x), it lies 2.5 m
    off that track. The waypoints stay Δv·frame + margin = 1 + 5 = 6 m right of the track
    (y = 14) either way (6.206), where an offset from the midpoint gives 16.5 / 11.5."""
    fast, slow = note("a", (-40, fast_y, 0), (2, 0, 0)), note("b", (-20, 20, 0), (1, 0, 0))
    case = compute_collision_case(fast, slow, 0.0, UtmConfig(time_margin=25.0))
    assert case.collision_point[1] == pytest.approx((fast_y + 20) / 2)
    div, conv = overtake_waypoints(fast.pos, fast.vel, slow.pos, slow.vel, case.collision_point, 5.0, 1.0, 2.0)
    assert div[:2] == pytest.approx([case.collision_point[0], 14.0])
    assert conv[1] == pytest.approx(14.0)
    assert conv[0] - div[0] == pytest.approx(np.sqrt(np.sum((fast.pos - case.collision_point) ** 2) + 25.0) + 1 + 2)


def test_pass_behind_point_trails_the_right_of_way_uas_until_the_give_way_uas_is_behind():
    """The converging give-way UAS aims ``offset`` behind the right-of-way UAS on its track
    (peer at the origin flying north, +y ENU), until it is itself that far behind it."""
    peer, north = np.zeros(3), np.array([0.0, 5.0, 0.0])
    assert pass_behind_point(peer, north, (-100.0, 0.0, 0.0), 45.0) == pytest.approx([0.0, -45.0, 0.0])
    assert pass_behind_point(peer, north, (-30.0, -44.0, 0.0), 45.0) == pytest.approx([0.0, -45.0, 0.0])
    assert pass_behind_point(peer, north, (-30.0, -45.0, 0.0), 45.0) is None  # a margin behind: back to the mission
    assert pass_behind_point(peer, np.zeros(3), (-100.0, 0.0, 0.0), 45.0) is None  # no course to pass behind


def test_lower_priority_gives_way_whatever_the_side():
    haps = note("haps", (20, 0, 0), (0, 1, 0), maneuverability=Maneuverability.LINEAR_PROPULSION)
    quad = note("quad", (0, 20, 0), (1, 0, 0))  # would have the HAPS on its right anyway: swap sides
    case = compute_collision_case(note("quad", (40, 20, 0), (-1, 0, 0)), haps, 0.0, UtmConfig(time_margin=25.0))
    assert case.encounter == Encounter.CONVERGING and case.roles == (Role.CONVERGING, Role.RIGHT_OF_WAY)
    case = compute_collision_case(
        quad, note("balloon", (20, 0, 0), (0, 1, 0), category=Category.BALLOON), 0.0, UtmConfig(time_margin=25.0)
    )
    assert case.roles == (Role.CONVERGING, Role.RIGHT_OF_WAY)


def test_head_case_fixes_the_point_and_the_chain_closes_after_passing():
    book = CaseBook(UtmConfig(time_margin=25.0, close_after=2))
    opened, _ = book.update([note("a", (-1, 20, 0), (1, 0, 0), -1.0), note("b", (41, 20, 0), (-1, 0, 0), -1.0)], -1.0)
    assert not opened  # flagged once: waits for a confirming frame
    opened, _ = book.update([note("a", (0, 20, 0), (1, 0, 0)), note("b", (40, 20, 0), (-1, 0, 0))], 0.0)
    assert len(opened) == 1 and opened[0].head == 0.0
    # next frame b has drifted: the chained case keeps the head's point and roles
    book.update([note("a", (1, 19, 0), (1, 0, 0), 1.0), note("b", (39, 23, 0), (-1, 0, 0), 1.0)], 1.0)
    (c,) = book.active("a")
    assert c.collision_point == pytest.approx([20, 20, 0]) and c.head == 0.0 and c.t == 1.0
    # past each other: closes on the second diverging frame (hysteresis)
    _, closed = book.update([note("a", (25, 15, 0), (1, 0, 0), 25.0), note("b", (15, 25, 0), (-1, 0, 0), 25.0)], 25.0)
    assert not closed and book.active("a")
    _, closed = book.update([note("a", (26, 15, 0), (1, 0, 0), 26.0), note("b", (14, 25, 0), (-1, 0, 0), 26.0)], 26.0)
    assert len(closed) == 1 and not book.active()


def test_books_that_share_heads_close_a_pair_together_once_it_is_quiet_in_all_of_them():
    """Two authorities' books over one pair (shared heads): one of them has b's notification
    still short of the pass at 25 s (a different link), so it counts the pair quiet a frame
    later. Neither closes the chain until both have counted it quiet for ``close_after`` frames,
    then both close it in the same frame (each closing alone: one book a frame without it)."""
    heads = SharedHeads()
    cfg = UtmConfig(time_margin=25.0, close_after=2)
    books = [CaseBook(cfg, shared=heads), CaseBook(cfg, shared=heads)]

    def frame(t: float, b_pos: list[tuple[float, float, float]]) -> set[tuple[str, str]]:
        for book, pos in zip(books, b_pos, strict=True):
            book.assess([note("a", (t, 20, 0), (1, 0, 0), t), note("b", pos, (-1, 0, 0), t)], t)
        closing = closing_together(books)
        for book in books:
            book.close(closing)
        return closing

    for t in (-1.0, 0.0):
        frame(t, [(40 - t, 20, 0)] * 2)
    assert [len(b.active()) for b in books] == [1, 1]
    assert books[0].active()[0].head == books[1].active()[0].head == 0.0
    assert not frame(25.0, [(15, 25, 0), (21, 22, 0)])  # the second book: b still 4.5 m off a
    assert not frame(26.0, [(14, 25, 0), (14, 25, 0)])  # the first book's chain is due, not the second's
    assert [len(b.active()) for b in books] == [1, 1]
    assert frame(27.0, [(13, 25, 0), (13, 25, 0)]) == {("a", "b")}
    assert not books[0].active() and not books[1].active() and not heads.heads


def test_overtake_chain_closes_only_once_the_overtaking_uas_is_the_margin_ahead():
    """Overtake (a at 2 m/s behind b at 1 m/s on one line, margin 5 m): abeam and 6 m apart on a's
    parallel offset the case stays open; it closes once a is 5 m ahead along b's course."""
    book = CaseBook(UtmConfig(time_margin=25.0, close_after=1))
    for t in (0.0, 1.0):
        book.update([note("a", (-40 + 2 * t, 20, 0), (2, 0, 0), t), note("b", (-20 + t, 20, 0), (1, 0, 0), t)], t)
    ((c,),) = [book.active("a")]
    assert c.encounter == Encounter.OVERTAKE and c.roles == (Role.OVERTAKING, Role.OVERTAKEN)
    for x_a, x_b, t in ((20.0, 20.0, 40.0), (23.0, 21.0, 41.0)):  # abeam, then 2 m ahead: open
        _, closed = book.update([note("a", (x_a, 14, 0), (2, 0, 0), t), note("b", (x_b, 20, 0), (1, 0, 0), t)], t)
        assert not closed and book.active("a")
    _, closed = book.update([note("a", (27, 14, 0), (2, 0, 0), 43.0), note("b", (22, 20, 0), (1, 0, 0), 43.0)], 43.0)
    assert len(closed) == 1 and not book.active()


def test_a_pair_in_a_case_stays_assessed_while_the_slow_uas_reads_below_the_hover_speed():
    """Overtake (a at 2 m/s 20 m behind b at 1 m/s on one line; hover gate 0.5 m/s, chains close
    after 2 quiet frames). A pair not in a case whose slow UAS reads 0.4 m/s is not assessed; once
    flagged, the dip does not stop the confirming frame from opening the case, and two frames of
    0.4 m/s mid-manoeuvre (a 3 m right of b's line) keep the head's overtake, roles and head time
    (dropped, the chain would close and re-open with the geometry of that moment). Once b really
    hovers (0.1 m/s, below half the gate) the chain stays open while a comes up to and passes
    abeam of b, and closes after 2 frames in which a is past b and the case margin away from it
    (ended by the hover itself, a give-way UAS hovering out its soft deadlock met its peer again as
    a fresh head-on case inside the margin: finding 19)."""
    book = CaseBook(UtmConfig(time_margin=25.0, min_speed=0.5, close_after=2))
    book.update([note("a", (-40, 20, 0), (2, 0, 0)), note("b", (-20, 20, 0), (0.4, 0, 0))], 0.0)
    assert not book.assessed and not book.pending  # hovering and in no case: no approach direction
    book.update([note("a", (-40, 20, 0), (2, 0, 0), 1.0), note("b", (-20, 20, 0), (1, 0, 0), 1.0)], 1.0)
    assert ("a", "b") in book.pending
    opened, _ = book.update([note("a", (-38, 20, 0), (2, 0, 0), 2.0), note("b", (-19, 20, 0), (0.4, 0, 0), 2.0)], 2.0)
    overtake = (Encounter.OVERTAKE, (Role.OVERTAKING, Role.OVERTAKEN))
    assert [(c.encounter, c.roles, c.head) for c in opened] == [(*overtake, 2.0)]
    for t in (3.0, 4.0):  # a diverged 3 m right, b's track reads 0.4 m/s
        a = note("a", (-36 + 2 * (t - 3), 17, 0), (2, 0, 0), t)
        _, closed = book.update([a, note("b", (-18, 20, 0), (0.4, 0, 0), t)], t)
        assert not closed and ("a", "b") in book.assessed
    ((c,),) = [book.active("a")]
    assert (c.encounter, c.roles, c.head, c.t) == (*overtake, 2.0, 4.0)
    margin = c.margin
    # b really hovers (0.1 m/s): behind, abeam, past but inside the margin, then twice the margin away
    for x, t in ((-34, 5.0), (-32, 6.0), (-18, 7.0), (-18 + 0.5 * margin, 8.0), (-18 + margin, 9.0)):
        _, closed = book.update([note("a", (x, 17, 0), (2, 0, 0), t), note("b", (-18, 20, 0), (0.1, 0, 0), t)], t)
        assert not closed and book.active("a")
    far = [note("a", (-16 + margin, 17, 0), (2, 0, 0), 10.0), note("b", (-18, 20, 0), (0.1, 0, 0), 10.0)]
    _, closed = book.update(far, 10.0)
    assert [c.ids for c in closed] == [("a", "b")] and not book.active("a")


def test_a_case_of_two_hovering_uas_closes_once_they_are_the_margin_apart():
    """Head-on pair (a east, b west on one line, 1 m/s, hover gate 0.5 m/s) whose case is open:
    both hovering (0.1 m/s) 6 m apart, inside the case margin, keep it open for any number of
    frames; hovering the margin apart, it closes after the 2 quiet frames (a hovering UAS counts as
    heading away and has no closest approach to pass)."""
    book = CaseBook(UtmConfig(time_margin=25.0, min_speed=0.5, close_after=2))
    for t in (0.0, 1.0):
        book.update([note("a", (t, 20, 0), (1, 0, 0), t), note("b", (40 - t, 20, 0), (-1, 0, 0), t)], t)
    ((c,),) = [book.active("a")]
    assert c.encounter == Encounter.HEAD_ON and c.margin > 6.0
    for t in (2.0, 3.0, 4.0, 5.0):
        _, closed = book.update([note("a", (17, 20, 0), (0.1, 0, 0), t), note("b", (23, 20, 0), (-0.1, 0, 0), t)], t)
        assert not closed and ("a", "b") in book.assessed
    for t in (6.0, 7.0):
        apart = [note("a", (17, 20, 0), (0.1, 0, 0), t), note("b", (17 + c.margin, 20, 0), (0.1, 0, 0), t)]
        _, closed = book.update(apart, t)
    assert [k.ids for k in closed] == [("a", "b")] and not book.active()


def test_four_way_encounter_merges_into_one_roundabout():
    book = CaseBook(UtmConfig(time_margin=25.0))
    notes = [
        note("1", (0, 20, 0), (1, 0, 0)),
        note("2", (40, 20, 0), (-1, 0, 0)),
        note("3", (20, 0, 0), (0, 1, 0)),
        note("4", (20, 40, 0), (0, -1, 0)),
    ]
    book.update(notes, 0.0)
    assert not book.active()
    book.update([dataclasses.replace(n, t=1.0, pos=n.pos + n.vel) for n in notes], 1.0)
    assert len(book.active()) == 6
    (rb,) = book.roundabouts()
    assert rb.members == {"1", "2", "3", "4"} and rb.centre == pytest.approx([20, 20, 0])
    assert rb.margin == pytest.approx(10.0)


def test_filed_registration_of_a_peer_ranks_it():
    cfg = RulesConfig(filed={"haps": {"maneuverability": "linear_propulsion"}})
    assert cfg.registration("haps", 5.0).priority() < cfg.registration("uas2", 5.0).priority()
    with pytest.raises(ValueError, match="unknown maneuverability 'jet'"):
        RulesConfig(filed={"haps": {"maneuverability": "jet"}})
    with pytest.raises(ValueError, match=r"filed\.haps: a table"):
        RulesConfig(filed={"haps": "glider"})


def test_rules_config_errors_name_the_field():
    with pytest.raises(ValueError, match="unknown rule"):
        RulesConfig.from_options({"enabled": ["head_on", "fly_left"]})
    with pytest.raises(ValueError, match="unknown option"):
        RulesConfig.from_options({"margin": 3})
    with pytest.raises(ValueError, match="airspace"):
        RulesConfig.from_options({"airspace": "class g"})


# -- restrictions ----------------------------------------------------------------------------------
def test_restrictions_disable_left_and_inside_the_margin():
    pose = GridPose(np.zeros(3), 0.0)
    cp = np.array([8.0, 0.0, 0.0])
    left = right_plane_heading_mask(NAV, pose, cp)
    tips = NAV.tip
    assert left.any() and not left[0]
    assert (tips[left, 1].max() > 0) and (NAV.samples[~left][..., 1] <= 1e-6).all()
    ball = safety_margin_mask(NAV, pose, cp, 5.0)
    dist = np.linalg.norm(NAV.samples[~ball] - cp, axis=-1)
    assert ball.any() and dist.min() >= 5.0 - 1e-9
    barrel = safety_margin_mask(NAV, pose, cp + [0, 0, 10.0], 5.0, barrel_half_height=3.0)
    assert not barrel.any()  # 10 m above the band's half height: nothing disabled
    # already inside the ball: keep what does not get closer than now
    inside = safety_margin_mask(NAV, pose, np.array([3.0, 0, 0]), 5.0)
    assert not inside.all()


def _lateral(pose: GridPose, cp: np.ndarray, lcf: np.ndarray) -> np.ndarray:
    """Signed distance [m] of LCF points left (+) of the line grid origin -> collision point."""
    c = pose.to_lcf(cp)[:2]
    u = c / np.linalg.norm(c)
    return u[0] * lcf[:, 1] - u[1] * lcf[:, 0]


def _resolve(pose: GridPose, cp: np.ndarray, goal: np.ndarray, margin: float):
    parts = ThreatParts.empty(GRID.n_cells)
    fused = fuse(NAV, parts, Categories(), CFG.fusion.threshold)
    fused.node_ok &= ~(right_plane_heading_mask(NAV, pose, cp) | safety_margin_mask(NAV, pose, cp, margin))
    return find_best_path(GRID, NAV, fused, pose.to_lcf(goal))


@settings(max_examples=60, deadline=None)
@given(alpha=st.floats(0.5, 179.5), r=st.floats(12.0, 20.0), k=st.floats(0.5, 2.0), rot=st.floats(-np.pi, np.pi))
def test_classification_agrees_with_the_angle_thresholds(alpha, r, k, rot):
    """Both UAS fly straight at a common point, arriving together: the case is flagged there,
    α equals the geometric angle and the encounter follows the thresholds."""
    if min(abs(alpha - 130.0), abs(alpha - 70.0)) < 0.05 or abs(abs(k - 1.0) - 0.2) < 1e-6:
        return  # on a threshold
    cp = np.array([3.0, -2.0, 0.0])
    d1 = np.array([np.cos(rot), np.sin(rot), 0.0])
    a = np.radians(alpha)
    d2 = np.array([np.cos(rot + a), np.sin(rot + a), 0.0])
    s1, s2 = 1.0, 1.0 * k
    n1, n2 = note("a", cp + r * d1, -s1 * d1), note("b", cp + k * r * d2, -s2 * d2)
    case = compute_collision_case(n1, n2, 0.0, UtmConfig(time_margin=25.0))
    assert case.flagged and case.t_cpa == pytest.approx(r, rel=1e-6)
    assert case.collision_point == pytest.approx(cp, abs=1e-6)
    assert case.alpha_deg == pytest.approx(alpha, abs=1e-6)
    expected = (
        Encounter.HEAD_ON
        if alpha >= 130
        else Encounter.CONVERGING
        if alpha >= 70
        else Encounter.OVERTAKE
        if abs(s1 - s2) > 0.2
        else Encounter.CONVERGING
    )
    assert case.encounter == expected
    if expected == Encounter.CONVERGING and 80 <= alpha <= 120:  # outside the doubts: exactly one gives way, the one
        # with the other on its right (within them a UAS in doubt gives way too)
        assert sorted(case.roles) == sorted((Role.CONVERGING, Role.RIGHT_OF_WAY))
        assert (case.roles[0] == Role.CONVERGING) == (np.cross(-d1, d2 - d1)[2] < 0)


@settings(max_examples=25, deadline=None)
@given(alpha=st.floats(130.01, 180.0), r=st.floats(18.0, 20.5), rot=st.floats(-np.pi, np.pi))
def test_head_on_encounters_both_turn_right(alpha, r, rot):
    """Head-on (α ≥ 130°, equal speeds): both roundabout and both chosen navigation paths keep the
    collision point on their left: never left of their approach line, deviating right of it, and
    outside the margin. (r < margin + grid range: the ball blocks the straight path inside the
    grid; farther away going straight on is still allowed.)"""
    cp = np.array([20.0, 20.0, 0.0])
    a = np.radians(alpha)
    dirs = [np.array([np.cos(rot), np.sin(rot), 0.0]), np.array([np.cos(rot + a), np.sin(rot + a), 0.0])]
    notes = [note(u, cp + r * d, -d) for u, d in zip("ab", dirs, strict=False)]
    case = compute_collision_case(*notes, 0.0, UtmConfig(time_margin=25.0))
    assert case.roles == (Role.ROUNDABOUT, Role.ROUNDABOUT)
    for n, d in zip(notes, dirs, strict=False):
        pose = GridPose(n.pos, float(np.arctan2(-d[1], -d[0])))
        path = _resolve(pose, case.collision_point, cp - 30.0 * d, case.margin + 1.0)
        assert path.ok
        lateral = _lateral(pose, case.collision_point, NAV.path_samples(path.node))
        assert lateral.max() <= 1e-6 and lateral.min() < -1.0  # right of the line to the point
        assert (
            np.linalg.norm(NAV.path_samples(path.node) - pose.to_lcf(case.collision_point), axis=1).min() >= case.margin
        )


@settings(max_examples=15, deadline=None)
@given(r=st.floats(18.0, 20.5), rot=st.floats(-np.pi, np.pi), shift=st.floats(-50, 50))
def test_symmetric_head_on_resolves_symmetrically(r, rot, shift):
    """Exactly opposite approaches: the two UAS choose the same manoeuvre in their own frames."""
    cp = np.array([shift, -shift, 0.0])
    d = np.array([np.cos(rot), np.sin(rot), 0.0])
    notes = [note("a", cp + r * d, -d), note("b", cp - r * d, d)]
    case = compute_collision_case(*notes, 0.0, UtmConfig(time_margin=25.0))
    paths = []
    for n, sign in zip(notes, (1, -1), strict=False):
        pose = GridPose(n.pos, float(np.arctan2(-sign * d[1], -sign * d[0])))
        paths.append(_resolve(pose, case.collision_point, cp - sign * 30.0 * d, case.margin + 1.0))
    assert paths[0].ok and NAV.buffer(paths[0].node) == NAV.buffer(paths[1].node)
    assert NAV.path_samples(paths[0].node)[:, 1].min() < -1.0  # both deviate right (LCF Y+ = left)


def test_moving_margin_follows_the_peer_in_time():
    pose = GridPose(np.zeros(3), 0.0)
    # a peer crossing 6 m ahead from the right at 1 m/s: where it is when the samples get there
    mask = moving_margin_mask(NAV, pose, np.array([6.0, -6.0, 0.0]), np.array([0.0, 1.0, 0.0]), 3.0)
    times = NAV.sample_times()
    peer = np.array([6.0, -6.0, 0.0]) + times[..., None] * np.array([0.0, 1.0, 0.0])
    dist = np.linalg.norm(NAV.samples - peer, axis=-1)
    assert mask.any() and (dist[~mask] >= 3.0 - 1e-9).all()
    # the same peer standing still at its start blocks other trajectories
    static = moving_margin_mask(NAV, pose, np.array([6.0, -6.0, 0.0]), np.zeros(3), 3.0)
    assert (mask != static).any()


@pytest.mark.parametrize(
    "old, new, message",
    [
        ('"head_on", "converging"', '"head_on", "converge"', "unknown rule(s) converge"),
        ("rules_settle = 10.0", "rules_settle = -1", "settle must be >= 0"),
        ("rules_unit = 5.0", "rules_units = 5.0", "planner.options.rules_units: unknown key"),
    ],
)
def test_bad_rules_options_are_one_line_scenario_errors(old, new, message, tmp_path):
    path = Path(__file__).resolve().parents[1] / "scenarios" / "rules" / "s9_converging.toml"
    bad = tmp_path / "bad.toml"
    bad.write_text(path.read_text().replace(old, new, 1))
    with pytest.raises(ScenarioError, match=re.escape(message)) as err:
        load_scenario(bad)
    assert "\n" not in str(err.value)


def _avoider_with_traffic(
    cooperative: bool, ahead: float, frames: int = 3, turns_in_place: bool = False, from_right: bool = False
):
    """A thesis-scale RulesAvoider flying north at 1 m/s with one peer: head-on ``ahead`` [m],
    or (``from_right``) ``ahead`` north and east of it flying west, converging at 90° with the
    UAS giving way; its decisions at t = 0, 1, ... ``frames`` - 1 s."""
    from avoidance.reachset.movement import thesis_automaton
    from avoidance.rules.planner import RulesAvoider
    from sim.core.mission import Mission
    from sim.core.plan import Threats
    from sim.core.state import VehicleState
    from sim.core.threats import IntruderTrack

    mission = Mission(np.array([[60.0, 0.0, -5.0]]), cruise_speed=1.0, acceptance_radius=2.0)
    av = RulesAvoider(mission, thesis_automaton(), RulesConfig(), turns_in_place=turns_in_place)

    def peer(t):
        if from_right:
            pos, vel = np.array([ahead, ahead - t, -5.0]), np.array([0, -1.0, 0])
        else:
            pos, vel = np.array([ahead - t, 0.0, -5.0]), np.array([-1.0, 0, 0])
        return IntruderTrack("peer", t, pos, vel, cooperative=cooperative)

    decisions = []
    for t in np.arange(float(frames)):
        est = VehicleState(
            t=t,
            pos_ned=np.array([t, 0.0, -5.0]),
            vel_ned=np.array([1.0, 0.0, 0.0]),
            euler=np.zeros(3),
            rates_body=np.zeros(3),
            alt_msl_m=5.0,
            lat_deg=0.0,
            lon_deg=0.0,
        )
        av.plan(est, Threats(intruders=[peer(t)]), t)
        decisions.append(av.last_decision)
    return av, decisions


def test_cooperative_peer_is_resolved_by_the_rules_in_navigation_mode():
    av, decisions = _avoider_with_traffic(cooperative=True, ahead=40.0)
    d = decisions[1]  # the case opens on the second (confirming) frame
    assert d.mode.value == "navigation" and "intruder" not in d.events and d.status == "ok"
    assert (
        "rule:case_open:self-peer:head_on:roundabout" in d.events
        and "rule:head_on:self-peer:head_on:roundabout" in d.events
    )
    assert d.reference.positions[-1][0] > 1.0  # turned right: the UAS flies north (ENU +y), right is east (+x)
    assert av.rules_record["cases"][0]["encounter"] == "head_on"


def test_non_cooperative_intruder_falls_back_to_the_emergency_avoidance():
    _av, decisions = _avoider_with_traffic(cooperative=False, ahead=15.0)
    assert decisions[-1].mode.value == "emergency" and "intruder" in decisions[-1].events
    assert not any(e.startswith("rule:") for d in decisions for e in d.events)


def test_widest_keeps_one_trajectory_per_cell_the_farthest_from_the_point():
    pose = GridPose(np.zeros(3), 0.0)
    cp = np.array([20.0, 0.0, 0.0])
    clearance = path_clearance(NAV, pose, cp[None])
    samples_min = np.array([np.linalg.norm(NAV.path_samples(n) - cp, axis=1).min() for n in range(NAV.n_nodes)])
    np.testing.assert_allclose(clearance, samples_min, atol=1e-9)
    feasible = np.ones(NAV.n_nodes, bool)
    kept = feasible & ~widest_per_cell(NAV, feasible, clearance)
    cells = NAV.tip_cell[kept & (NAV.tip_cell >= 0)]
    assert len(cells) == len(np.unique(cells)) == len(np.unique(NAV.tip_cell[NAV.tip_cell >= 0]))
    for c in np.unique(cells)[:20]:
        in_cell = np.flatnonzero(NAV.tip_cell == c)
        assert clearance[kept & (NAV.tip_cell == c)][0] == clearance[in_cell].max()
    assert not widest_per_cell(NAV, np.zeros(NAV.n_nodes, bool), clearance).any()


def test_managed_peer_is_an_intruder_while_another_threat_holds_the_emergency_mode():
    """A non-cooperative intruder crossing ahead holds the UAS in emergency mode while a
    cooperative head-on peer's case is open. Emergency runs have no rule restrictions, so the peer
    must be an intruder there: the run's feasible trajectories are those with a non-cooperative
    peer in its place (it used to be dropped from the run: more trajectories, some through it)."""
    from avoidance.reachset.movement import thesis_automaton
    from avoidance.rules.planner import RulesAvoider
    from sim.core.mission import Mission
    from sim.core.plan import Threats
    from sim.core.state import VehicleState
    from sim.core.threats import IntruderTrack

    def decisions(cooperative: bool) -> list:
        mission = Mission(np.array([[60.0, 0.0, -5.0]]), cruise_speed=1.0, acceptance_radius=2.0)
        av = RulesAvoider(mission, thesis_automaton(), RulesConfig())
        out = []
        for t in (0.0, 1.0):
            peer = IntruderTrack(
                "peer", t, np.array([12.0 - t, 0, -5]), np.array([-1.0, 0, 0]), cooperative=cooperative
            )
            crossing = IntruderTrack("nc", t, np.array([6.0, -6.0 + t, -5.0]), np.array([0.0, 1.0, 0.0]))
            est = VehicleState(t, np.array([t, 0, -5.0]), np.array([1.0, 0, 0]), np.zeros(3), np.zeros(3), 5.0, 0, 0)
            av.plan(est, Threats(intruders=[peer, crossing]), t)
            out.append(av.last_decision)
        return out

    coop, non_coop = decisions(True)[1], decisions(False)[1]
    assert "rule:case_open:self-peer:head_on:roundabout" in coop.events  # the rules manage the peer
    assert coop.mode.value == "emergency"
    np.testing.assert_array_equal(coop.run.fused.node_ok, non_coop.run.fused.node_ok)


def _every_path_closed(monkeypatch):
    """The safety-margin rule disables every navigation node: a soft deadlock every frame."""
    from avoidance.rules import rules_of_air

    def close_all(self, ctx, engine):
        tree, _pose = ctx.navigation_tree()
        ctx.disable(self.code, np.ones(tree.n_nodes, bool), ctx.current_case())

    monkeypatch.setattr(rules_of_air.EnforceSafetyMargin, "apply", close_all)


def test_a_hovering_uas_waits_out_a_soft_deadlock_while_the_peer_keeps_the_margin(monkeypatch):
    """With every restricted path closed, a UAS that hovers (``turns_in_place``) and gives way to
    a peer converging from its right (28 m away, closing at 1.4 m/s) stops at the grid origin
    (``stop``, ``rule:hold``) while the peer stays beyond the case margin + bloat (9 m) over the
    next two periods; the frames held are no deadlock. After ``HOLD_FRAMES`` holds in a row it
    flies the old plan on and three blocked frames later hands the peer to the emergency
    avoidance. A UAS that cannot hover, or a head-on peer (which resolves too, and might wait as
    well), never holds."""
    from avoidance.rules.planner import HOLD_FRAMES

    def holds(decisions):
        return [("stop" in d.events and any(e.startswith("rule:hold") for e in d.events)) for d in decisions]

    def blocked(decisions):
        return [i for i, d in enumerate(decisions) if "rule:deadlock" in d.events]

    _every_path_closed(monkeypatch)
    frames = HOLD_FRAMES + 5
    av, decisions = _avoider_with_traffic(True, 20.0, frames, turns_in_place=True, from_right=True)
    assert "rule:case_open:self-peer:converging:converging" in decisions[1].events
    assert holds(decisions) == [False] + [True] * HOLD_FRAMES + [False] * 4
    assert all(d.status == "ok" for d in decisions[1 : 1 + HOLD_FRAMES])
    assert blocked(decisions) == [HOLD_FRAMES + 1, HOLD_FRAMES + 2, HOLD_FRAMES + 3] and "peer" in av.emergency
    av, flying = _avoider_with_traffic(True, 20.0, 5, from_right=True)
    assert not any(holds(flying)) and blocked(flying) == [1, 2, 3] and "peer" in av.emergency
    _av, head_on = _avoider_with_traffic(True, 40.0, 5, turns_in_place=True)
    assert "rule:case_open:self-peer:head_on:roundabout" in head_on[1].events
    assert not any(holds(head_on)) and blocked(head_on) == [1, 2, 3]


def test_no_hold_when_the_peer_comes_inside_the_margin_meanwhile(monkeypatch):
    """7 m north and east of the UAS, converging from its right at 1.4 m/s, the peer comes within
    the 9 m margin + bloat within two periods: hovering would not keep the margin, no hold."""
    _every_path_closed(monkeypatch)
    _av, decisions = _avoider_with_traffic(True, 7.0, 3, turns_in_place=True, from_right=True)
    assert any(e.startswith("rule:case_open") for e in decisions[1].events)
    assert not any(any(e.startswith("rule:hold") for e in d.events) for d in decisions)
