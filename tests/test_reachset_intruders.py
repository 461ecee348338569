"""Intruder ratings (spec §5.4): exact point-to-cell distances, the swept body against a brute
force of its points, the sample step and memory blocks, and the exact culling of intruders that
cannot reach the grid (ratings and whole decisions unchanged)."""

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from avoidance.reachset.config import AvoidanceConfig
from avoidance.reachset.frames import from_polar
from avoidance.reachset.grid import AvoidanceGrid
from avoidance.reachset.gridrun import closest_approach
from avoidance.reachset.mission import MissionControl, Mode
from avoidance.reachset.movement import KinState, thesis_automaton
from avoidance.reachset.threats.intruders import IntruderModel
from sim.core.plan import Threats
from sim.core.threats import IntruderTrack

CFG = AvoidanceConfig()
GRID = AvoidanceGrid(CFG.grid.scaled(5.0))  # the shipped scale: L = 5 m, range 50 m


def cell_lattice(grid: AvoidanceGrid, n: int) -> np.ndarray:
    """(n_cells, n³ + 8, 3) LCF points filling every cell (cell-centred lattice + corners)."""
    u = (np.arange(n) + 0.5) / n
    uu = np.stack(np.meshgrid(u, u, u, indexing="ij"), -1).reshape(-1, 3)
    uu = np.vstack([uu, np.stack(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij"), -1).reshape(-1, 3)])
    return from_polar(grid.lower[:, None, :] + uu[None] * grid.steps)


def model(grid: AvoidanceGrid, **cfg) -> IntruderModel:
    """Intruder model of a grid with a UAS window [0, 6] s in every cell."""
    n = grid.n_cells
    return IntruderModel(grid, np.zeros(n), np.full(n, 6.0), dataclasses.replace(CFG.intruders, **cfg))


def test_distance_is_exact_against_a_dense_lattice_of_every_cell():
    """Never above the distance to any point of the cell; at most the lattice's half spacing
    (the polar cell's largest lattice gap) below the nearest lattice point; 0 inside."""
    rng = np.random.default_rng(3)
    pts = np.vstack([rng.uniform(-60, 60, (60, 3)), from_polar(GRID.centers_polar[::17])])
    lattice = cell_lattice(GRID, 10)
    brute = np.array([np.linalg.norm(lattice - p, axis=-1).min(axis=1) for p in pts])
    d = GRID.distance(pts)
    gap = np.linalg.norm(GRID.steps * [1.0, 50.0, 50.0]) / 10  # lattice spacing at the far wall
    assert (d <= brute + 1e-9).all()
    assert (brute - d).max() <= gap
    cells = GRID.cell_index(pts)
    inside = cells >= 0
    assert inside.sum() >= 20
    assert (d[np.flatnonzero(inside), cells[inside]] == 0.0).all()
    np.testing.assert_allclose(GRID.envelope_distance(pts), d.min(axis=1), atol=1e-9)  # the union's distance


def test_near_pairs_are_exactly_the_cells_within_each_points_bound():
    """``near`` finds the same (point, cell) pairs as the full distance matrix, also where the
    bound equals the exact distance (its lower-bound pre-tests must not drop a pair at the edge)."""
    rng = np.random.default_rng(5)
    pts = np.vstack([rng.uniform(-70, 70, (400, 3)), from_polar(GRID.centers_polar[::7])])
    d = GRID.distance(pts)
    for bound in (rng.uniform(0.0, 8.0, len(pts)), d[np.arange(len(pts)), rng.integers(0, GRID.n_cells, len(pts))]):
        rows, cells = GRID.near(pts, bound)
        np.testing.assert_array_equal(np.stack([rows, cells], axis=1), np.argwhere(d <= bound[:, None]))
    assert len(GRID.near(pts, np.full(len(pts), 1.0))[0]) > len(pts) // 4  # the cases hold pairs


def test_body_rating_covers_the_swept_body_and_stays_within_one_sample_of_it():
    """An intruder crossing the grid (5 m body, 5 m/s): every cell that holds a point of the swept
    body (brute force: lattice points within the radius of the path) is hit, no cell farther from
    the path than radius + half a sample is, and the hit times contain the brute-force times of
    arrival (each body point carries its centre's time) to within one sample. Straight-line
    prediction only (the give-way turn, D-21: tests/test_reachset_give_way.py)."""
    m = model(GRID, timed=False, give_way_turn_rate=0.0)
    x, v, r = np.array([30.0, -20.0, 3.0]), np.array([-2.0, 4.5, -0.5]), 5.0
    motion = np.array([[*x, *v, r]])
    hit, i_e, i_l = m._body(motion, np.linalg.norm(motion[:, 3:6], axis=1))
    tau = np.linspace(0.0, m.horizon, 600)
    path = x + tau[:, None] * v
    lattice = cell_lattice(GRID, 5)
    dt = m.horizon / (m._samples(float(np.linalg.norm(v))) - 1)
    for c in range(GRID.n_cells):
        d = np.linalg.norm(lattice[c][:, None, :] - path[None], axis=-1)  # (points, times)
        near = (d <= r).any(axis=0)
        if near.any():
            assert hit[0, c], c
            assert i_e[0, c] <= tau[near].min() + dt and i_l[0, c] >= tau[near].max() - dt
        if GRID.distance(path[::10]).min(axis=0)[c] > r + 0.5 * np.linalg.norm(v) * dt + 0.2:
            assert not hit[0, c], c
    assert 0 < hit.sum() < GRID.n_cells
    np.testing.assert_array_equal(m.ratings(motion)[0], hit[0])


def capsule_distance(points: np.ndarray, centres: np.ndarray, half_height: float) -> np.ndarray:
    """(points, centres) distance [m] of points to the vertical segments centre ± half_height."""
    d = points[:, None, :] - centres[None]
    dz = np.clip(np.abs(d[..., 2]) - half_height, 0.0, None)
    return np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2 + dz**2)


def test_vertical_margin_stretches_the_swept_body_into_a_vertical_capsule():
    """Finding 11 (docs/encounters.md): an intruder crossing 7.5 m above the grid's centre plane
    (5 m body, 4 m/s) with a 2.5 m vertical margin: every cell holding a point within the radius
    of the swept vertical segment (brute force) is hit, none farther than radius + half a sample
    along the path + half a sample vertically, and the capsule hits cells the ball alone does
    not (its lower end reaches 2.5 m further down)."""
    m0 = model(GRID, timed=False, give_way_turn_rate=0.0)
    m = model(GRID, timed=False, give_way_turn_rate=0.0, vertical_margin=2.5)
    x, v, r, e = np.array([25.0, -20.0, 7.5]), np.array([0.0, 4.0, 0.0]), 5.0, 2.5
    motion = np.array([[*x, *v, r]])
    hit = m._body(motion, np.array([4.0]))[0][0]
    path = x + np.linspace(0.0, m.horizon, 400)[:, None] * v
    lattice = cell_lattice(GRID, 5)
    offsets, half_gap = m._vertical_offsets()
    assert offsets[0] == -e and offsets[-1] == e and np.diff(offsets).max() <= m.step + 1e-12
    dt = m.horizon / (m._samples(4.0) - 1)
    axis = (path[::4, None, :] + np.linspace(-e, e, 51)[None, :, None] * [0.0, 0.0, 1.0]).reshape(-1, 3)
    far = GRID.distance(axis).min(axis=0)  # exact cell distances to the capsule's axis (0.1 m samples)
    for c in range(GRID.n_cells):
        near = capsule_distance(lattice[c], path, e).min() <= r
        if near:
            assert hit[c], c
        if far[c] > r + 0.5 * 4.0 * dt + half_gap + 0.3:
            assert not hit[c], c
    ball = m0.ratings(motion)[0] > 0
    assert (hit >= ball).all() and hit.sum() > ball.sum()
    assert m.reachable(motion).all() and (m.reach(motion) >= m0.reach(motion) + e).all()


def test_closest_approach_is_measured_to_the_capsule():
    """The last resort's clearance (D-18) against a vertical capsule: a path passing straight
    under an intruder 9 m above clears a 5 m ball by 4 m and a ±2.5 m capsule by 1.5 m."""
    tree = MissionControl(np.array([[30.0, 0.0, 0.0]]), thesis_automaton(), CFG).segment(0).trees[Mode.NAVIGATION]
    straight = int(np.flatnonzero((tree.depth == 1) & (tree.movement == 0))[0])
    motion = np.array([[0.5, 0.0, 9.0, 0.0, 0.0, 0.0, 5.0]])  # hovering above the first movement
    ball = closest_approach(tree, motion, 0.0)[straight]
    capsule = closest_approach(tree, motion, 0.0, vertical_margin=2.5)[straight]
    assert ball == pytest.approx(4.0, abs=1e-9) and capsule == pytest.approx(1.5, abs=1e-9)


def test_path_step_is_the_centre_spacing_and_a_coarse_step_still_covers():
    motion = np.array([[40.0, -25.0, 0.0, -3.0, 5.0, 0.0, 4.0]])
    fine, coarse = model(GRID, timed=False, path_step=0.05), model(GRID, timed=False, path_step=1.0)
    assert coarse._samples(5.83) < fine._samples(5.83)
    a, b = fine.ratings(motion)[0], coarse.ratings(motion)[0]
    assert (b >= a).all() and b.sum() > a.sum()  # half a coarse step grows the body


def test_blocks_of_bounded_size_give_the_same_ratings():
    rng = np.random.default_rng(5)
    motion = np.column_stack([rng.uniform(-40, 40, (6, 3)), rng.uniform(-6, 6, (6, 3)), rng.uniform(0, 6, 6)])
    whole = model(GRID).ratings(motion)
    m = model(GRID)
    m.max_block = GRID.n_cells * 3  # three centre samples per block
    np.testing.assert_array_equal(m.ratings(motion), whole)
    assert whole.any()


def test_far_intruders_are_culled_and_near_ones_not():
    """A HAPS 17 km above and a quadrotor 2 km away cannot reach the 50 m grid within the
    horizon; an intruder 120 m ahead flying at the grid at 15 m/s can."""
    m = model(GRID)
    motion = np.array(
        [
            [0.0, 0.0, 17000.0, 26.0, 0.0, 0.0, 17.5],
            [2000.0, 0.0, 0.0, -5.0, 0.0, 0.0, 5.0],
            [120.0, 0.0, 0.0, -15.0, 0.0, 0.0, 5.0],
        ]
    )
    assert m.reachable(motion).tolist() == [False, False, True]
    r = m.ratings(motion)
    assert not r[:2].any() and r[2].any()


@settings(max_examples=150, deadline=None)
@given(
    ahead=st.floats(-0.8, 0.8),
    up=st.floats(-0.5, 0.5),
    gap=st.floats(-8.0, 40.0),
    vel=st.tuples(st.floats(-6, 6), st.floats(-6, 6), st.floats(-2, 2)),
    radius=st.floats(0.0, 8.0),
)
def test_culled_ratings_equal_the_full_ratings_near_the_grid_boundary(ahead, up, gap, vel, radius):
    """Intruders placed just around the grid's bounding ball (``gap`` beyond the range, in the
    directions of the grid's front): culling leaves every rating as without it."""
    m = model(GRID)
    direction = np.array([np.cos(up) * np.cos(ahead), np.cos(up) * np.sin(ahead), np.sin(up)])
    motion = np.array([[*(direction * (GRID.range + radius + gap)), *vel, radius]])
    culled = m.ratings(motion)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(IntruderModel, "reachable", lambda self, motion: np.ones(len(motion), bool))
        np.testing.assert_array_equal(culled, m.ratings(motion))


@st.composite
def intruder_states(draw):
    """Intruders around the thesis-scale grid (range 10 m): positions within 40 m, speeds up to
    4 m/s, bodies up to 3 m, some pointed at the grid."""
    n = draw(st.integers(1, 4))
    out = []
    for k in range(n):
        pos = np.array([draw(st.floats(-40, 40)) for _ in range(3)])
        if draw(st.booleans()):
            vel = -pos / max(np.linalg.norm(pos), 1e-6) * draw(st.floats(0.0, 4.0))
        else:
            vel = np.array([draw(st.floats(-4, 4)) for _ in range(3)])
        out.append(IntruderTrack(f"i{k}", 0.0, pos, vel, draw(st.floats(0.1, 3.0))))
    return out


def decide(tracks: list[IntruderTrack], cull: bool, monkeypatch) -> tuple:
    if not cull:
        monkeypatch.setattr(IntruderModel, "reachable", lambda self, motion: np.ones(len(motion), bool))
    ctl = MissionControl(np.array([[30.0, 0.0, 0.0]]), thesis_automaton(), CFG)
    d = ctl.step(KinState(np.zeros(3), np.zeros(3), 0.0, 1.0), Threats(intruders=tracks))
    monkeypatch.undo()
    run = d.run
    return (
        d.mode,
        tuple(d.events),
        tuple(d.buffer),
        d.status,
        d.selected,
        None if run is None else run.fused.intruder.tobytes(),
    )


@settings(max_examples=40, deadline=None)
@given(tracks=intruder_states())
def test_culling_never_changes_a_decision(tracks):
    """For random intruder states the decision (mode, events, buffer, status, selected run and
    the fused intruder ratings) with culling equals the one with every intruder rated."""
    with pytest.MonkeyPatch.context() as mp:
        assert decide(tracks, True, mp) == decide(tracks, False, mp)


def test_culling_test_sees_intruders_that_matter():
    """The decisions compared above do react to intruders (else the comparison proves nothing)."""
    with pytest.MonkeyPatch.context() as mp:
        head_on = [IntruderTrack("i", 0.0, np.array([0.0, 8.0, 0.0]), np.array([0.0, -1.0, 0.0]), 1.0)]
        assert decide(head_on, True, mp)[0].value == "emergency"
        assert decide([], True, mp)[0].value == "navigation"
