"""Flyability from the start state: the first leg begins with a turn at the minimum radius from
the current course (no anticipation), so its target must lie outside that turning circle, and
every plan the search accepts must be flown by ``flyby_path`` from the start course."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import box

from guidance.mptp.config import MptpConfig
from guidance.mptp.goal import GoalTrack
from guidance.mptp.search import plan_trajectory
from guidance.mptp.timeline import ObstacleTimeline
from guidance.mptp.turning import admissible, aux_states, flyby_path, start_turn, wrap
from sim.core.threats import StormSnapshot

CFG = MptpConfig()
R = CFG.turn_radius_m


def test_a_target_inside_the_start_turning_circle_is_rejected():
    """44 deg right of the course at the fly-by minimum leg (the old rule accepted it): the
    right turning circle (centre 1 R east) contains it, and flyby_path cannot fly it."""
    chi = math.radians(44.0)
    leg = R * (math.tan(0.5 * chi) + math.tan(0.5 * CFG.course_change_max)) + 1.0
    target = np.array([[leg * math.cos(chi), leg * math.sin(chi)]])
    assert np.linalg.norm(target[0] - [0.0, R]) < R
    ok, _, _ = admissible(np.zeros(2), 0.0, target, CFG, from_start=True)
    assert not ok[0]
    assert admissible(np.zeros(2), 0.0, target, CFG)[0][0]  # a fly-by state may (it anticipates)
    with pytest.raises(ValueError, match="turning circle"):
        flyby_path(np.vstack([np.zeros(2), target]), 0.0, R)


def test_start_turn_exit_course_and_distance():
    """A target 1 R right and far ahead of a northbound start: the turn's exit course points
    from the tangent point at it; the flown distance is the arc plus the tangent."""
    target = np.array([[10_000.0, R]])
    reachable, turn, chi, straight = start_turn(np.zeros(2), 0.0, target, R)
    assert reachable[0] and turn[0] > 0 and chi[0] == pytest.approx(turn[0])
    exit_pt = np.array([R * math.sin(turn[0]), R * (1 - math.cos(turn[0]))])
    assert math.atan2(*(target[0] - exit_pt)[::-1]) == pytest.approx(chi[0], abs=1e-9)
    assert straight[0] == pytest.approx(np.linalg.norm(target[0] - exit_pt))


def test_start_auxiliary_states_are_a_dchi_max_turn_then_straight():
    pts, chi = aux_states(np.zeros(2), 0.3, CFG, "both", from_start=True)
    ok, chi_in, dist = admissible(np.zeros(2), 0.3, pts, CFG, from_start=True)
    assert ok.all() and np.allclose(chi_in, chi) and np.allclose(dist, CFG.leg_m)
    assert np.allclose(np.abs(wrap(chi - 0.3)), CFG.course_change_max)


@settings(max_examples=300, deadline=None)
@given(
    course0=st.floats(-math.pi, math.pi),
    off1=st.floats(-math.pi, math.pi),
    r1=st.floats(1.0, 8.0),
    off2=st.floats(-1.0, 1.0),
    r2=st.floats(0.2, 8.0),
    to_goal=st.booleans(),
)
def test_every_accepted_first_and_second_leg_is_flyable(course0, off1, r1, off2, r2, to_goal):
    p0 = np.zeros(2)
    q1 = p0 + r1 * R * np.array([math.cos(course0 + off1), math.sin(course0 + off1)])
    ok1, chi1, _ = admissible(p0, course0, q1[None], CFG, from_start=True)
    if not ok1[0]:
        return
    q2 = q1 + r2 * R * np.array([math.cos(chi1[0] + off2), math.sin(chi1[0] + off2)])
    ok2, _, _ = admissible(q1, float(chi1[0]), q2[None], CFG, to_goal=to_goal)
    if not ok2[0]:
        return
    path = flyby_path(np.vstack([p0, q1, q2]), course0, R)
    assert np.linalg.norm(path[-1] - q2) < 1e-6


def _one_storm_timeline() -> ObstacleTimeline:
    cfg = MptpConfig(safety_single_m=(1000.0,) * 3, sigma_front_mps=0.0, sigma_back_mps=0.0)
    storm = StormSnapshot(0.0, (box(6_000, -2_000, 10_000, 2_000),), np.zeros((1, 2)))
    return ObstacleTimeline([storm], cfg, 7200.0)


TL = _one_storm_timeline()


EDGE_A, EDGE_B = np.array([5_123.6, -2_876.4]), np.array([4_760.6, -2_000.0])  # a margin edge (south-west)


@settings(max_examples=60, deadline=None)
@given(
    along=st.floats(0.75, 0.97),
    off=st.floats(5.0, 100.0),
    turn=st.floats(0.35, 0.78),
    sense=st.sampled_from([-1.0, 1.0]),
    goal_e=st.floats(-4_000.0, 4_000.0),
)
def test_every_plan_of_the_search_is_flyable_from_the_start_heading(along, off, turn, sense, goal_e):
    """Starts just outside a margin edge, short of its corner, heading 20-45 deg off the edge:
    the corner (a tangent vertex) is then often inside the start's turning circle. Complete or
    partial, every plan is flown by flyby_path from the start course."""
    cfg = TL.cfg.with_(max_expansions=40)
    u = (EDGE_B - EDGE_A) / np.linalg.norm(EDGE_B - EDGE_A)
    p0 = EDGE_A + along * (EDGE_B - EDGE_A) + off * np.array([-u[1], u[0]])
    course0 = math.atan2(u[1], u[0]) + sense * turn
    traj = plan_trajectory(TL, p0, 0.0, course0, GoalTrack.fixed([16_000.0, goal_e]), cfg, min_partial_s=0.0)
    if len(traj.positions) >= 2:  # none when heading into the margin too close to turn away
        flyby_path(traj.positions, course0, cfg.turn_radius_m)
