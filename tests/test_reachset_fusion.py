"""Threat ratings and data fusion (spec §5, T-LI-1/2, T-MO-1/2, T-DF-1/2) and their properties."""

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from avoidance.reachset.cache import reach_set
from avoidance.reachset.config import ConstraintConfig, LidarConfig, MapConfig, MovementConfig, ReachSetConfig
from avoidance.reachset.frames import GridPose
from avoidance.reachset.fusion import Categories, SpaceClass, ThreatParts, fuse, fuse_cells, reachability
from avoidance.reachset.grid import AvoidanceGrid
from avoidance.reachset.movement import build_primitive_table
from avoidance.reachset.threats.constraints import Constraint, classify, from_geofence
from avoidance.reachset.threats.lidar import lidar_ratings_polar
from avoidance.reachset.threats.map_obstacles import MapObstacle, map_rating
from sim.core.threats import Geofence

GRID = AvoidanceGrid()
TREE = reach_set(GRID, build_primitive_table(MovementConfig()), ReachSetConfig.combined())
N = GRID.n_cells
THR = 1e-7


def middle_row(values):
    return GRID.per_cell(values)[:, 3, 2]


def row_rays(n: int) -> np.ndarray:
    """``n`` ray directions inside the middle column of the grid (θ, φ near 0)."""
    th = np.linspace(-0.1, 0.1, n)
    return np.column_stack([th, np.zeros(n)])


def hits_at(d: float, rays: np.ndarray) -> np.ndarray:
    return np.column_stack([np.full(len(rays), d), rays])


def test_cells_beyond_the_sensor_range_are_not_visible():
    """A ray that ends at the sensor's range without a return has not seen the cells beyond it:
    with half the row's rays ending at 4.5 m and the other half at 7.5 m, layers 1-5 are seen by
    all, 6-8 by half, 9-10 by none (before: all visible, so (6.158) erased the map there)."""
    rays = row_rays(20)
    reach = np.r_[np.full(10, 4.5), np.full(10, 7.5)]
    _, vis = lidar_ratings_polar(GRID, rays, np.zeros((0, 3)), LidarConfig(), reach)
    np.testing.assert_allclose(middle_row(vis), np.r_[np.ones(5), np.full(3, 0.5), np.zeros(2)], atol=1e-12)
    scans = hits_at(2.5, rays[:5])  # returns hinder as before, on top
    _, vis = lidar_ratings_polar(GRID, rays, scans, LidarConfig(), np.where(np.arange(20) < 5, np.inf, reach))
    np.testing.assert_allclose(
        middle_row(vis), np.r_[np.ones(3), np.full(2, 0.75), np.full(3, 0.5), np.zeros(2)], atol=1e-12
    )


def test_visibility_worked_example():
    rays = row_rays(20)
    scans = [hits_at(2.5, rays[:5]), hits_at(4.5, rays[5:8]), hits_at(6.5, rays[8:12])]  # 0.25, 0.15, 0.20
    expected = [
        np.r_[np.ones(3), np.full(7, 0.75)],
        np.r_[np.ones(3), 0.75, 0.75, np.full(5, 0.60)],
        np.r_[np.ones(3), 0.75, 0.75, 0.60, 0.60, np.full(3, 0.40)],
    ]
    _, vis0 = lidar_ratings_polar(GRID, rays, np.zeros((0, 3)), LidarConfig())
    np.testing.assert_allclose(middle_row(vis0), 1.0)
    for n, want in enumerate(expected, 1):
        _, vis = lidar_ratings_polar(GRID, rays, np.vstack(scans[:n]), LidarConfig())
        np.testing.assert_allclose(middle_row(vis), want, atol=1e-12)
    assert (vis[GRID.per_cell(np.arange(N))[:, 0, 0]] == 0.0).all()  # rows without rays are not visible


def fig_6_10_scan(distance: float):
    """One ray per grid row at its centre elevation, 2.2° apart; a 1 m wide, 0.5 m high plate."""
    th = np.radians(2.2) * np.arange(-20, 21)
    th = th[np.abs(th) < np.pi / 4]
    phi = np.radians([-24.0, -12.0, 0.0, 12.0, 24.0])
    rays = np.array([(t, p) for t in th for p in phi])
    hit = (np.abs(distance * np.tan(rays[:, 0])) <= 0.5) & (rays[:, 1] == 0.0)
    return rays, hits_at(distance, rays[hit])[:, :] * np.c_[1 / np.cos(rays[hit, 0]), np.ones((hit.sum(), 2))]


def test_lidar_same_rating_at_5m_with_5_hits_and_10m_with_3_hits():
    rays5, hits5 = fig_6_10_scan(4.5)  # fig. 6.10's 5 m / 10 m, placed mid-layer (layers 5 and 10)
    rays10, hits10 = fig_6_10_scan(9.5)
    assert (len(hits5), len(hits10)) == (5, 3)
    obs5, _ = lidar_ratings_polar(GRID, rays5, hits5, LidarConfig())
    obs10, _ = lidar_ratings_polar(GRID, rays10, hits10, LidarConfig())
    c5, c10 = GRID.cell_index_polar(hits5[:1])[0], GRID.cell_index_polar(hits10[:1])[0]
    assert obs5[c5] == obs10[c10] == 1.0  # the same object, fully counted at both ranges
    assert np.count_nonzero(obs5) == np.count_nonzero(obs10) == 1


def plate_scan(distance: float, half: float = 0.3, step_deg: float = 0.4):
    """Fine lattice LiDAR against a square plate ⊥ X at ``distance``: ray directions and hits."""
    a = np.radians(np.arange(-44.8, 45.0, step_deg))
    e = np.radians(np.arange(-29.8, 30.0, step_deg))
    rays = np.stack(np.meshgrid(a, e, indexing="ij"), axis=-1).reshape(-1, 2)
    y = distance * np.tan(rays[:, 0])
    z = distance * np.tan(rays[:, 1]) / np.cos(rays[:, 0])
    hit = (np.abs(y) <= half) & (np.abs(z) <= half)
    rng = distance / (np.cos(rays[hit, 0]) * np.cos(rays[hit, 1]))
    return rays, np.column_stack([rng, rays[hit]])


def test_lidar_rating_is_range_invariant_surface():
    cfg = LidarConfig(threshold_area=4.0)  # unsaturated
    ratings = []
    for dist in (4.6, 9.6):
        rays, hits = plate_scan(dist)
        obs, _ = lidar_ratings_polar(GRID, rays, hits, cfg)
        ratings.append(obs.sum())
        assert len(hits) > 0
    assert ratings[0] == pytest.approx(0.36 / 4.0, rel=0.1) and ratings[1] == pytest.approx(ratings[0], rel=0.1)


def test_map_obstacle_hindered_60_percent_gives_0_6():
    rays = row_rays(10)
    obstacle, vis = lidar_ratings_polar(GRID, rays, hits_at(2.5, rays[:6]), LidarConfig())
    target = GRID.per_cell(np.arange(N))[5, 3, 2]
    ball = MapObstacle(shapely.Point(0.0, 5.5), (0.0, 0.0), 0.0, radius=0.8)  # GCF: 5.5 m north of a north-facing grid
    pose = GridPose(np.zeros(3), np.pi / 2)
    m = map_rating(GRID, pose, [ball], MapConfig())
    assert m[target] == 1.0
    parts = ThreatParts(vis[None], obstacle[None], m, np.zeros((0, N)), np.zeros(N, bool), np.zeros(N, bool))
    vis_f, _, map_f, *_ = fuse_cells(parts, Categories(), THR)
    assert vis_f[target] == pytest.approx(0.4) and map_f[target] == pytest.approx(0.6)
    # undetected map obstacle in a fully visible cell (T-MO-2): rated 0
    parts.visibility = np.ones((1, N))
    assert fuse_cells(parts, Categories(), THR)[2][target] == 0.0


def test_two_intruders_of_half_each_fuse_to_0_75():
    parts = ThreatParts.empty(N)
    parts.intruders = np.full((2, N), 0.5)
    intruder = fuse_cells(parts, Categories(), THR)[3]
    np.testing.assert_allclose(intruder, 0.75)
    assert (fuse_cells(parts, Categories(intruders=False), THR)[3] == 0).all()


def test_thresholds_and_space_classes():
    parts = ThreatParts.empty(N)
    parts.visibility = np.ones((1, N))
    parts.obstacle = np.zeros((1, N))
    parts.obstacle[0, 0] = 1e-7
    parts.visibility[0, 1] = 1 - 1.1e-7
    parts.intruders = np.zeros((1, N))
    parts.intruders[0, 2] = 2e-7
    parts.hard[3] = True
    parts.soft[4] = True
    cls = fuse_cells(parts, Categories(), THR)[6]
    assert cls[:6].tolist() == [
        SpaceClass.OCCUPIED,
        SpaceClass.UNCERTAIN,
        SpaceClass.CONSTRAINED,
        SpaceClass.CONSTRAINED,
        SpaceClass.CONSTRAINED,
        SpaceClass.FREE,
    ]
    assert fuse_cells(parts, Categories(soft=False), THR)[6][4] == SpaceClass.FREE


def test_constraints_hard_soft_and_moving():
    pose = GridPose(np.zeros(3), 0.0)  # LCF x = east
    body = shapely.box(6.0, -1.0, 7.0, 1.0)
    _, leave = TREE.uas_entry_leave()
    hard, soft = classify(GRID, pose, [Constraint(body, (-5.0, 5.0), 1.0)], ConstraintConfig(), 0.0, leave)
    assert hard.any() and soft.any() and not (hard & soft).any()
    assert not hard[GRID.layer < 5].any()
    circle_hard, _ = classify(
        GRID, pose, [Constraint(body, (-5.0, 5.0), 1.0)], ConstraintConfig(mode="circle"), 0.0, leave
    )
    assert (circle_hard >= hard).all() and circle_hard.sum() > hard.sum()
    moving = Constraint(shapely.box(16.0, -1.0, 17.0, 1.0), (-5.0, 5.0), 1.0, np.array([-1.0, 0.0]), 0.0)
    m_hard, _ = classify(GRID, pose, [moving], ConstraintConfig(), 0.0, leave)
    assert m_hard.any() and not m_hard[GRID.layer < 4].any()  # it meets the UAS half-way
    above = classify(GRID, pose, [Constraint(body, (20.0, 30.0), 1.0)], ConstraintConfig(), 0.0, leave)
    assert not above[0].any() and not above[1].any()
    fence = Geofence("f", shapely.box(-100, -100, 100, 100), -50.0, 50.0)  # NE square
    keep_in = classify(GRID, pose, [from_geofence(fence, 5.0)], ConstraintConfig(), 0.0, leave)
    assert not keep_in[0].any() and not keep_in[1].any()
    tight = Geofence("f", shapely.box(-100, -100, 100, 5.0), -50.0, 50.0)  # east edge at 5 m
    h, s = classify(GRID, pose, [from_geofence(tight, 2.0)], ConstraintConfig(), 0.0, leave)
    assert h[GRID.layer >= 6].any() and s.any() and not h[GRID.layer < 3].any()


unit = st.floats(0.0, 1.0)


@settings(max_examples=60, deadline=None)
@given(
    arrays(float, (2, N), elements=unit),
    arrays(float, (1, N), elements=unit),
    arrays(float, N, elements=unit),
    arrays(float, (3, N), elements=unit),
    arrays(bool, N),
    arrays(bool, N),
)
def test_fusion_stays_in_unit_interval(vis, obs, map_, intr, hard, soft):
    parts = ThreatParts(vis, np.vstack([obs, obs]), map_, intr, hard, soft)
    f = fuse(TREE, parts, Categories(), THR)
    for a in (f.visibility, f.obstacle, f.map, f.intruder, f.constraint, f.threat, f.node_reach, f.cell_reach):
        assert np.all((a >= 0.0) & (a <= 1.0))
    assert not (f.reachable & ~f.free).any()


@settings(max_examples=60, deadline=None)
@given(arrays(float, N, elements=st.floats(0.0, 0.5)), arrays(float, N, elements=st.floats(0.0, 0.5)))
def test_reachability_is_monotone_in_threat(threat, extra):
    free = np.ones(N, bool)
    r1, ok1, c1, _ = reachability(TREE, threat, free, 0.02)
    r2, ok2, c2, _ = reachability(TREE, threat + extra, free, 0.02)
    assert np.all(r2 <= r1 + 1e-12) and np.all(c2 <= c1 + 1e-12) and not (ok2 & ~ok1).any()
    parent = TREE.parent[1:]
    assert np.all(r1[1:] <= r1[parent] + 1e-12)  # along a trajectory reachability only drops


@settings(max_examples=60, deadline=None)
@given(arrays(float, (2, N), elements=unit), arrays(float, N, elements=unit))
def test_more_intruders_and_hits_only_add_threat(intr, more):
    parts = ThreatParts.empty(N)
    parts.intruders = intr
    base = fuse_cells(parts, Categories(), THR)[3]
    parts.intruders = np.vstack([intr, more])
    assert np.all(fuse_cells(parts, Categories(), THR)[3] >= base - 1e-12)


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.tuples(st.integers(0, 19), st.floats(0.1, 10.0)), max_size=30), st.integers(0, 19), st.floats(0.1, 10.0)
)
def test_an_extra_hit_never_increases_visibility(hits, ray, dist):
    rays = row_rays(20)
    pts = np.array([[d, *rays[r]] for r, d in hits]).reshape(-1, 3)
    _, v1 = lidar_ratings_polar(GRID, rays, pts, LidarConfig())
    _, v2 = lidar_ratings_polar(GRID, rays, np.vstack([pts, [dist, *rays[ray]]]), LidarConfig())
    assert np.all(v2 <= v1 + 1e-12) and np.all((v2 >= 0) & (v2 <= 1))
