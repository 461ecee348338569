"""Give-way convention of the reach-set avoider (D-21, docs/reachset.md): every intruder is also
predicted turning right at ``give_way_turn_rate`` (in the intruder space and in the last resort's
clearance), and the last resort turns right. Two non-cooperative vehicles that each predicted the
other on its straight line passed behind each other and turned into each other (S8)."""

import dataclasses

import numpy as np
import pytest

from avoidance.reachset.config import AvoidanceConfig
from avoidance.reachset.frames import GridPose
from avoidance.reachset.grid import AvoidanceGrid
from avoidance.reachset.gridrun import closest_approach, emergency_runs, passing_on_the_right
from avoidance.reachset.mission import MissionControl, Mode
from avoidance.reachset.movement import KinState
from avoidance.reachset.movement import MovementType as M
from avoidance.reachset.options import ReachSetOptions
from avoidance.reachset.threats.intruders import IntruderModel, predicted_positions
from sim.core.plan import Threats
from sim.core.threats import IntruderTrack
from tests.test_reachset_mission_end import fly

SPEED = 5.0  # [m/s] S8's cruise speed
GIVE_WAY = np.pi / 12  # [rad/s] the thesis' 15° per 1 s movement
YAW_SIGN = {M.LEFT: 1, M.UP_LEFT: 1, M.DOWN_LEFT: 1, M.RIGHT: -1, M.UP_RIGHT: -1, M.DOWN_RIGHT: -1}


def s8_config(
    intruder_margin: float, rate: float = GIVE_WAY, separation: str = "horizontal"
) -> tuple[ReachSetOptions, AvoidanceConfig]:
    """S8's options for one planar set, with the give-way turn rate ``rate`` [rad/s]."""
    opt = ReachSetOptions(period=1.0, intruder_margin=intruder_margin, separations=[separation])
    cfg = opt.avoidance_config()
    return opt, dataclasses.replace(cfg, intruders=dataclasses.replace(cfg.intruders, give_way_turn_rate=rate))


def test_predicted_positions_follow_a_right_turn_at_the_rate():
    """Closed form against an Euler integration of a constant right turn (LCF z up, Y left), and
    the straight line at rate 0."""
    pos, vel, rate = np.array([3.0, -2.0, 1.0]), np.array([4.0, 3.0, 0.5]), 0.3
    t = np.linspace(0.0, 12.0, 7)
    dt = 1e-4
    steps = np.arange(int(12.0 / dt))
    course = np.arctan2(vel[1], vel[0]) - rate * dt * steps
    vh = np.hypot(vel[0], vel[1])
    path = np.cumsum(np.stack([vh * np.cos(course), vh * np.sin(course)], axis=1) * dt, axis=0)
    idx = np.rint(t / dt).astype(int) - 1
    expect = pos[:2] + np.vstack([[0.0, 0.0], path[idx[1:]]])
    got = predicted_positions(pos, vel, t, rate)
    np.testing.assert_allclose(got[:, :2], expect, atol=2e-3)
    np.testing.assert_allclose(got[:, 2], pos[2] + vel[2] * t)
    assert got[2, 1] < pos[1] + vel[1] * t[2]  # right of the straight line
    np.testing.assert_allclose(predicted_positions(pos, vel, t, 0.0), pos + t[:, None] * vel)


def test_intruder_space_holds_the_right_turn_only_with_a_rate():
    """An intruder crossing ahead from left to right: with the give-way rate the cells of its
    right-turn arc (brute force: cells holding arc points) are rated, with rate 0 they are not."""
    _, cfg = s8_config(4.55)
    grid = AvoidanceGrid(cfg.grid.scaled(SPEED))  # S8's 5 m movements
    n = grid.n_cells
    motion = np.array([[25.0, 20.0, 0.0, 0.0, -SPEED, 0.0, 1.0]])

    def rated(rate: float) -> np.ndarray:
        icfg = dataclasses.replace(cfg.intruders, give_way_turn_rate=rate, timed=False)
        return IntruderModel(grid, np.zeros(n), np.full(n, 10.0), icfg).ratings(motion)[0] > 0

    tau = np.linspace(0.0, 10.0, 200)
    arc = predicted_positions(motion[0, :3], motion[0, 3:6], tau, GIVE_WAY)
    line = motion[0, :3] + tau[:, None] * motion[0, 3:6]
    arc_cells = np.unique(grid.cell_index(arc))
    arc_cells = arc_cells[arc_cells >= 0]
    away = arc_cells[grid.distance(line).min(axis=0)[arc_cells] > 2.0]  # arc cells clear of the line's body
    assert len(away) > 5
    assert rated(GIVE_WAY)[arc_cells].all()
    assert not rated(0.0)[away].any()


def last_resort(course_b_deg: float, rate: float) -> tuple[list[list[M]], float]:
    """Two vehicles of S8's type 25 m before a common crossing point, B on a course
    ``course_b_deg`` from A's (NED, clockwise), each deciding once against the other with a body
    (0.45 m + 12 m margin) that no path clears: the selected runs' buffers and the smallest
    distance [m] between the two paths flown together."""
    opt, cfg = s8_config(12.0, rate)
    mc = MissionControl(np.zeros((1, 3)), opt.automaton("multirotor", SPEED), cfg)
    seg = mc.segment(mc.sma.active_index(KinState(np.zeros(3), np.zeros(3), 0.0, SPEED)))
    tree, grid = seg.trees[Mode.EMERGENCY], seg.grid
    cross = np.array([25.0, 0.0, -20.0])
    courses = (0.0, np.radians(course_b_deg))
    heads = [np.array([np.cos(c), np.sin(c), 0.0]) for c in courses]
    starts = [cross - 25.0 * h for h in heads]
    buffers, paths = [], []
    for me, other in ((0, 1), (1, 0)):
        pose = GridPose.from_ned(starts[me], courses[me])
        track = IntruderTrack("o", 0.0, starts[other], SPEED * heads[other], radius_m=0.45)
        parts = seg.assessors[Mode.EMERGENCY].assess(pose, 0.0, Threats(intruders=[track]))
        runs, sel = emergency_runs(grid, tree, parts, pose.ned_to_lcf(cross + 200.0 * heads[me]), 1e-7)
        assert sel == 3, sel  # the last resort: intruders dropped
        buffers.append(tree.buffer(runs[sel].path.node))
        paths.append(pose.lcf_to_ned(tree.path_samples(runs[sel].path.node)))
    n = min(len(p) for p in paths)
    return buffers, float(np.linalg.norm(paths[0][:n] - paths[1][:n], axis=1).min())


@pytest.mark.parametrize("course_b", [135.0, -135.0, 180.0])
def test_symmetric_pair_turns_right_in_the_last_resort_and_keeps_apart(course_b):
    """Converging at 135° (either side) and head-on, both in the last resort: both turn right
    first and never left of their heading, and the two paths flown together stay > 15 m apart
    (measured 22.8 m converging, 24.7 m head-on)."""
    buffers, joint = last_resort(course_b, GIVE_WAY)
    for b in buffers:
        assert b[0] == M.RIGHT, b
        assert np.cumsum([YAW_SIGN.get(m, 0) for m in b]).max() <= 0, b  # never left of the heading
    assert joint > 15.0, joint


@pytest.mark.parametrize("course_b", [135.0, -135.0])
def test_without_the_give_way_rate_the_converging_pair_turns_into_each_other(course_b):
    """The same encounter on straight-line predictions only (rate 0, D-18): one vehicle turns
    left, the other right, each behind the other's line, and the paths meet (measured 0.39 m)."""
    buffers, joint = last_resort(course_b, 0.0)
    assert {buffers[0][0], buffers[1][0]} == {M.LEFT, M.RIGHT}
    assert joint < 2.0, joint


def fly_pair(rate: float, steps: int = 30) -> float:
    """S8's UAS1 (east-bound) and UAS4 (south-bound) meeting at the crossing, as two reach-set
    mission controls on exact tracks of each other, each flying its executing movement exactly
    (no airframe): the smallest distance between them [m]."""
    opt, cfg = s8_config(4.55, rate)
    enu = [((0.0, 100.0, 20.0), 0.0, (225.0, 100.0, 20.0)), ((100.0, 200.0, 20.0), -90.0, (100.0, -25.0, 20.0))]
    mcs = [MissionControl(np.array([g]), opt.automaton("multirotor", SPEED), cfg) for _, _, g in enu]
    states = [KinState(np.array(p), np.array([0.0, 0.0, np.radians(h)]), 0.0, SPEED) for p, h, _ in enu]
    vel = [SPEED * np.array([np.cos(s.att[2]), np.sin(s.att[2]), 0.0]) for s in states]
    closest = np.inf
    for _ in range(steps):
        new = []
        for i, (mc, s) in enumerate(zip(mcs, states, strict=True)):
            o, v = states[1 - i].pos, vel[1 - i]
            track = IntruderTrack("o", s.t, np.array([o[1], o[0], -o[2]]), np.array([v[1], v[0], -v[2]]), 0.45)
            d = mc.step(s, Threats(intruders=[track]))
            new.append(mc.sma.active(s).apply(s, d.executing))
        vel = [(n.pos - s.pos) / (n.t - s.t) for n, s in zip(new, states, strict=True)]
        states = new
        closest = min(closest, float(np.linalg.norm(states[0].pos - states[1].pos)))
    return closest


def test_s8_crossing_pair_keeps_apart_with_the_give_way_convention():
    """S8's crossing pair in the loop without airframes: with the give-way prediction each turns
    right and they stay > 6 m apart (S8's pass line; measured 16.9 m); on straight-line
    predictions both pass behind the other and meet (measured 3.9 m), as in the seed-4 log."""
    assert fly_pair(GIVE_WAY) > 12.0
    assert fly_pair(0.0) < 6.0


def test_a_set_whose_right_turns_descend_keeps_the_clearance_ranking():
    """The slash set turns right only descending (DownRight): its last resort is not bound to the
    right turn; an intruder ahead, a little to the right and below makes UpLeft the path of
    largest predicted clearance, and that is the one chosen."""
    opt, cfg = s8_config(12.0, separation="slash")
    mc = MissionControl(np.zeros((1, 3)), opt.automaton("multirotor", SPEED), cfg)
    seg = mc.segment(mc.sma.active_index(KinState(np.zeros(3), np.zeros(3), 0.0, SPEED)))
    tree, grid = seg.trees[Mode.EMERGENCY], seg.grid
    pose = GridPose.from_ned(np.array([0.0, 0.0, -20.0]), 0.0)
    track = IntruderTrack("o", 0.0, np.array([30.0, 4.0, -17.0]), np.array([-SPEED, 0.0, 0.0]), radius_m=0.45)
    parts = seg.assessors[Mode.EMERGENCY].assess(pose, 0.0, Threats(intruders=[track]))
    runs, sel = emergency_runs(grid, tree, parts, np.array([200.0, 0.0, 0.0]), 1e-7)
    assert sel == 3, sel
    leaves = tree.leaves()
    cand = leaves[runs[sel].fused.node_ok[leaves]]
    clearance = closest_approach(tree, parts.intruder_motion, parts.give_way_turn_rate)
    chosen = runs[sel].path.node
    assert clearance[chosen] >= clearance[cand].max() - 0.01
    assert tree.buffer(chosen)[0] == M.UP_LEFT


def test_passing_on_the_right_by_hand():
    """Ownship straight on at 5 m/s (LCF X); an intruder 40.62 m ahead, 3.05 m right, at
    (-3.96, -1.29) m/s: relative velocity (-8.96, -1.29), closest approach after
    (40.62 * 8.96 - 3.05 * 1.29) / (8.96² + 1.29²) = 4.39 s, 3.05 + 4.39 * 1.29 = 8.72 m to the
    right: clear of a 5 m body, not of a 9 m one; mirrored it passes on the left; exactly
    head-on it passes through; a receding intruder counts where it is now."""
    row = np.array([40.62, -3.05, 0.0, -3.96, -1.29, 0.0, 5.0])
    mirrored = row * np.array([1, -1, 1, 1, -1, 1, 1])
    big = row.copy()
    big[6] = 9.0
    head_on = np.array([40.0, 0.0, 0.0, -5.0, 0.0, 0.0, 5.0])
    receding = np.array([-10.0, -6.0, 0.0, -5.0, 0.0, 0.0, 5.0])
    got = passing_on_the_right(np.vstack([row, big, mirrored, head_on, receding]), 5.0)
    assert got.tolist() == [True, False, False, False, True]


def test_last_resort_does_not_cross_ahead_of_an_intruder_already_passing_on_the_right():
    """Finding 15 (docs/encounters.md, encounter 390 at 25 s): ownship north at 5 m/s with the
    campaign's options; a 4.2 m/s intruder 40.6 m ahead, 3.05 m right, level, on course 162°:
    flown straight on it would pass 8.72 m to the right (``test_passing_on_the_right_by_hand``).
    Its predicted right turn (the give-way convention) closes every path, so the last resort
    decides; ranking never-left-of-the-heading paths first turned right, across its track ahead
    of it (point mass: 0.7 m / 1.9 m, an NMAC). Now the largest clearance decides: the pass
    stays > 10 m (13.6 m)."""
    intruder = IntruderTrack("intruder", 0.0, np.array([40.62, 3.05, -20.0]), np.array([-3.96, 1.29, 0.0]), 0.45)
    cfg = ReachSetOptions(period=1.0, intruder_margin=4.55, intruder_margin_vertical=2.0).avoidance_config()
    trace: list = []
    fly(
        [[150.0, 0.0, -20.0]],
        1.0,
        start=(0.0, 0.0, -20.0),
        speed=5.0,
        t_end=12.0,
        cfg=cfg,
        intruder=intruder,
        trace=trace,
    )
    rel = np.array([q - p for _, p, q in trace])
    horizontal = np.hypot(rel[:, 0], rel[:, 1])
    assert horizontal.min() > 10.0, horizontal.min()
    assert horizontal[-1] > horizontal.min()  # the pair met and separates again
