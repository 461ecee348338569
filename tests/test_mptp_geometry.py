"""MPTP geometry against hand-computed cases: margins, merging, clustering, interpolation."""

import math

import numpy as np
import pytest
import shapely
from shapely.geometry import Point, Polygon, box

from guidance.mptp.config import MptpConfig
from guidance.mptp.margins import (
    close_gaps,
    margin_hulls,
    merge,
    probability_factor,
    safety_margin_m,
)
from guidance.mptp.timeline import ObstacleTimeline, minkowski_sequences
from sim.core.threats import StormSnapshot

CFG = MptpConfig(
    simplify_tol_m=0.0,
    safety_single_m=(1000.0, 1500.0, 2000.0),
    safety_line_m=(3000.0,) * 3,
    sigma_front_mps=2.0,
    sigma_back_mps=1.0,
    probability=0.9,
)


def test_probability_factor_is_the_rayleigh_quantile():
    k = probability_factor(0.9)
    assert 1 - math.exp(-k * k / 2) == pytest.approx(0.9)


def test_safety_margin_bands_and_lines():
    got = safety_margin_m(np.array([5.0, 15.0, 25.0, 5.0]), np.array([False, False, False, True]), CFG)
    assert got.tolist() == [1000.0, 1500.0, 2000.0, 3000.0]


def test_safety_margin_of_a_square_at_issue_time():
    # 10 km square, static, lead 0: the margin is the square buffered by 1 km (rounded corners)
    cell = box(0, 0, 10_000, 10_000)
    m = margin_hulls([cell], None, 0.0, CFG)[0]
    exact = 10_000**2 + 4 * 10_000 * 1000 + math.pi * 1000**2
    assert m.area == pytest.approx(exact, rel=0.01)
    assert m.contains(cell.buffer(999.0))
    assert m.hausdorff_distance(cell.buffer(1000.0)) < 30.0


def test_probabilistic_margin_grows_and_is_largest_ahead():
    cell = Point(0, 0).buffer(5000.0, quad_segs=16)
    v = np.array([[10.0, 0.0]])  # moving north
    k = probability_factor(0.9)
    m0 = margin_hulls([cell], v, 900.0, CFG)[0]
    m1 = margin_hulls([cell], v, 1800.0, CFG)[0]
    x0, _, x1, _ = m1.bounds
    ahead, behind = x1 - 5000.0, -5000.0 - x0
    grow = 1.0 / math.cos(math.pi / 16)  # the circles are circumscribed 16-gons
    assert 1500.0 + k * 2.0 * 1800 <= ahead <= (1500.0 + k * 2.0 * 1800) * grow + 1e-6  # 10 m/s: 1.5 km band
    assert 1500.0 + k * 1.0 * 1800 <= behind <= (1500.0 + k * 1.0 * 1800) * grow + 1e-6
    assert m1.contains(m0)


def test_concave_cells_are_convexified_and_margins_merge_concave():
    l_shape = Polygon([(0, 0), (4000, 0), (4000, 1000), (1000, 1000), (1000, 4000), (0, 4000)])
    m = margin_hulls([l_shape], None, 0.0, CFG)[0]
    assert m.contains(l_shape.convex_hull)
    a, b = box(0, 0, 2000, 2000), box(2500, 0, 4500, 2000)  # 500 m apart: margins overlap
    merged = merge(margin_hulls([a, b], None, 0.0, CFG), CFG)
    assert merged.geom_type == "Polygon"
    assert merged.convex_hull.area > merged.area  # the merge is concave and kept so


def test_clustering_closes_only_narrow_passages():
    a, b, c = box(0, 0, 10, 10), box(14, 0, 24, 10), box(40, 0, 50, 10)
    closed = close_gaps(shapely.union_all([a, b, c]), 6.0)
    assert len(shapely.get_parts(closed)) == 2  # the 4 m gap is filled, the 16 m one is not
    assert closed.contains(Point(12, 5)) and not closed.contains(Point(32, 5))


def test_minkowski_interpolation_of_a_moving_growing_square():
    a = np.array([[0, 0], [2, 0], [2, 2], [0, 2]], float)
    b = np.array([[10, 0], [14, 0], [14, 4], [10, 4]], float)
    ca, cb = minkowski_sequences(a, b)
    for s, lo, side in [(0.0, 0.0, 2.0), (0.5, 5.0, 3.0), (0.25, 2.5, 2.5), (1.0, 10.0, 4.0)]:
        p = Polygon((1 - s) * ca + s * cb)
        assert (
            p.equals_exact(box(lo, 0, lo + side, side).normalize(), 1e-9)
            or p.symmetric_difference(box(lo, 0, lo + side, side)).area < 1e-9
        )


def test_minkowski_of_square_and_triangle_has_the_mixed_area():
    sq = np.array([[0, 0], [2, 0], [2, 2], [0, 2]], float)
    tri = np.array([[0, 0], [4, 0], [0, 4]], float)
    ca, cb = minkowski_sequences(sq, tri)
    # area((A+B)/2) = (|A| + 2 V(A,B) + |B|)/4 with mixed area V(A,B) = 8 here (hand computed)
    assert Polygon(0.5 * ca + 0.5 * cb).area == pytest.approx((4 + 2 * 8 + 8) / 4)


def _one_cell_nowcast(speed_e=10.0):
    cell = box(-2000, -2000, 2000, 2000)
    snaps = [
        StormSnapshot(300.0 * k, (shapely.affinity.translate(cell, 0, speed_e * 300 * k),), np.array([[0.0, speed_e]]))
        for k in range(3)
    ]
    return snaps


def test_timeline_interpolates_between_nowcast_steps_and_envelopes_cover_the_interval():
    cfg = CFG.with_(dt_s=100.0, sigma_front_mps=0.0, sigma_back_mps=0.0)
    tl = ObstacleTimeline(_one_cell_nowcast(), cfg, 600.0)
    from guidance.mptp.margins import turn_cut_m

    r = 1500.0 + turn_cut_m(cfg)  # 10 m/s: second speed band
    for t in (0.0, 150.0, 450.0):
        shape = tl.shape_at(t)
        x0, y0, x1, y1 = shape.bounds
        assert (x0, x1) == pytest.approx((-2000 - r, 2000 + r), abs=r * 0.021)
        assert 0.5 * (y0 + y1) == pytest.approx(10.0 * t, abs=1.0)  # moves 10 m/s east
    env = tl.envelope(1)  # [100, 200] s
    for t in np.linspace(100.0, 200.0, 11):
        assert env.buffer(1e-6).contains(tl.shape_at(float(t)))
    assert tl.contains(np.array([[0.0, 1500.0], [0.0, -3500.0]]), np.array([150.0, 150.0])).tolist() == [True, False]


def test_cells_are_extrapolated_after_the_last_step():
    tl = ObstacleTimeline(
        _one_cell_nowcast()[:1], CFG.with_(dt_s=100.0, sigma_front_mps=0.0, sigma_back_mps=0.0), 1200.0
    )
    assert tl.shape_at(1200.0).centroid.y == pytest.approx(12_000.0, abs=50.0)


def test_line_smoothing_never_undercuts_the_margin():
    cell = Point(0, 0).buffer(8000.0, quad_segs=32)
    cfg = CFG.with_(simplify_tol_m=1500.0, sigma_front_mps=0.0, sigma_back_mps=0.0)
    tl = ObstacleTimeline([StormSnapshot(0.0, (cell,), None)], cfg, 600.0)
    smooth = tl.shape_at(0.0)
    assert smooth.contains(cell.buffer(1000.0 - 1.0))  # the 1 km safety margin is kept
    assert shapely.get_num_coordinates(smooth) < shapely.get_num_coordinates(cell.buffer(2500.0))
