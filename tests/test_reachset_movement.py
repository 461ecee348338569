"""Movement Automaton (spec §2, T-MA-1/2): integrated displacements, prediction, segments, reference."""

import numpy as np
import pytest

from avoidance.reachset.config import MovementConfig
from avoidance.reachset.movement import (
    KinState,
    MovementAutomaton,
    build_primitive_table,
    haps_automaton,
    multirotor_automaton,
    thesis_automaton,
)
from avoidance.reachset.movement import (
    MovementType as M,
)
from avoidance.reachset.reference import reference_trajectory

TABLE = {  # spec §2.3: Δpitch, Δyaw [deg], Δx, Δy, Δz [m]
    M.STRAIGHT: (0, 0, 1.0000, 0, 0),
    M.DOWN: (15, 0, 0.9886, 0, -0.1302),
    M.UP: (-15, 0, 0.9886, 0, 0.1302),
    M.LEFT: (0, 15, 0.9886, 0.1302, 0),
    M.RIGHT: (0, -15, 0.9886, -0.1302, 0),
    M.DOWN_LEFT: (15, 15, 0.9775, 0.1279, -0.1302),
    M.DOWN_RIGHT: (15, -15, 0.9775, -0.1279, -0.1302),
    M.UP_LEFT: (-15, 15, 0.9775, 0.1279, 0.1302),
    M.UP_RIGHT: (-15, -15, 0.9775, -0.1279, 0.1302),
}


def test_primitive_displacements_match_spec_table():
    t = build_primitive_table(MovementConfig())
    for m, (dp, dy, *dpos) in TABLE.items():
        np.testing.assert_allclose(t.d_pos_body[m], dpos, atol=1e-4)
        np.testing.assert_allclose(np.degrees(t.d_att[m, 1:]), [dp, dy], atol=1e-9)
    a = np.pi / 12
    np.testing.assert_allclose(t.d_pos_body[M.LEFT, :2], [np.sin(a) / a, (1 - np.cos(a)) / a], atol=1e-9)
    assert 1.0 / a == pytest.approx(3.8197, abs=1e-4) and 2.0 / a == pytest.approx(7.6394, abs=1e-4)


def test_prediction_rotates_displacement_by_attitude():
    ma = MovementAutomaton(build_primitive_table(MovementConfig()))
    s = KinState(np.array([1.0, 2.0, 3.0]), np.array([0.0, 0.0, np.pi / 2]), 0.0, 1.0)
    s1 = ma.apply(s, M.STRAIGHT)
    np.testing.assert_allclose(s1.pos, [1.0, 3.0, 3.0], atol=1e-12)
    assert s1.t == 1.0
    traj = ma.trajectory(s, [M.LEFT, M.LEFT, M.UP], sampled=True)
    assert traj.shape == (31, 7)
    np.testing.assert_allclose(traj[-1, :3], ma.trajectory(s, [M.LEFT, M.LEFT, M.UP])[-1, :3], atol=1e-12)
    np.testing.assert_allclose(ma.project(traj, 1.5)[6], 1.5)


def test_segmented_automata_scale_with_vehicle():
    mr = multirotor_automaton(cruise=3.0)
    slow = KinState(np.zeros(3), np.zeros(3), 0.0, 1.0)
    fast = KinState(np.zeros(3), np.zeros(3), 0.0, 3.0)
    assert mr.active(slow).table.config.speed == 1.0 and mr.active(fast).table.config.speed == 3.0
    assert mr.active(fast).table.config.dyaw <= np.pi / 12
    haps = haps_automaton(cruise=26.0)
    cruise = haps.active(KinState(np.zeros(3), np.zeros(3), 0.0, 26.0)).table.config
    assert cruise.length == 26.0
    assert cruise.dyaw == pytest.approx(9.80665 * np.tan(np.radians(20)) / 26.0)
    assert haps.active(KinState(np.zeros(3), np.zeros(3), 0.0, 20.0)).table.config.dyaw > cruise.dyaw
    chained = haps.trajectory(KinState(np.zeros(3), np.zeros(3), 0.0, 26.0), [M.STRAIGHT] * 3)
    np.testing.assert_allclose(chained[-1, 0], 78.0)
    assert len(thesis_automaton().segments) == 1


def test_reference_keeps_executing_movement_then_levels():
    ma = thesis_automaton().automata[0]
    s = KinState(np.zeros(3), np.array([0.0, np.pi / 12, 0.0]), 10.0, 1.0)
    ref = reference_trajectory(ma, s, M.DOWN, [M.STRAIGHT, M.STRAIGHT])
    np.testing.assert_allclose(ref.times, [10.0, 11.0, 12.0, 13.0])
    step = np.diff(ref.positions, axis=0)
    assert step[0, 2] < -0.2  # executing Down from a descending state
    np.testing.assert_allclose(step[1:], [[1.0, 0, 0], [1.0, 0, 0]], atol=1e-12)  # planned part starts level
