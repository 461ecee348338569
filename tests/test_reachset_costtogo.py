"""Cost-to-go around known constraints (avoidance/reachset/costtogo.py, D-17): z-up GCF x-y [m]."""

import numpy as np
from shapely.geometry import box

from avoidance.reachset.costtogo import CostToGo

SPACING = 2.5
EIGHT_CONNECTED = 1.0824  # worst ratio of an 8-connected raster path to the straight line (22.5°)


def test_open_field_is_the_straight_distance_within_the_raster_error():
    ctg = CostToGo(np.array([0.0, 100.0]), [], SPACING, 50.0, np.array([0.0, 0.0]))
    pts = np.array([[0.0, 0.0], [30.0, 20.0], [-40.0, 120.0], [0.0, 100.0]])
    straight = np.linalg.norm(pts - [0.0, 100.0], axis=1)
    v = ctg(pts)
    assert np.all(v >= straight - 1e-6)
    assert np.all(v <= straight * EIGHT_CONNECTED + SPACING)
    assert v[-1] == 0.0


def test_a_wall_makes_the_route_go_round_it():
    """Goal behind a 100 m wall (y 40..60): from (0, 0) the route passes a corner,
    2 * hypot(50, 40) + 20 = 148.1 m, not the straight 100 m."""
    ctg = CostToGo(np.array([0.0, 100.0]), [box(-50.0, 40.0, 50.0, 60.0)], SPACING, 50.0, np.array([0.0, 0.0]))
    around = 2.0 * np.hypot(50.0, 40.0) + 20.0
    v0 = float(ctg(np.array([0.0, 0.0])))
    assert around - 1e-6 <= v0 <= around * EIGHT_CONNECTED
    beside = float(ctg(np.array([60.0, 50.0])))  # level with the wall, past its end: nearly straight
    assert beside < np.hypot(60.0, 50.0) * EIGHT_CONNECTED
    inside = float(ctg(np.array([0.0, 50.0])))  # inside the body: finite, no shorter than from its face
    assert np.isfinite(inside) and inside > float(ctg(np.array([0.0, 62.5])))


def test_a_closed_pocket_is_farther_than_the_way_round_it():
    """A U open to the south (the S5 trap): the pocket's roof is closer to the goal in a straight
    line than the point beside the U, but farther along a route."""
    u = box(-60.0, 40.0, 60.0, 60.0).union(box(-60.0, -20.0, -40.0, 60.0)).union(box(40.0, -20.0, 60.0, 60.0))
    ctg = CostToGo(np.array([0.0, 120.0]), [u], SPACING, 50.0, np.array([0.0, -60.0]))
    roof, beside = np.array([0.0, 30.0]), np.array([75.0, 0.0])
    assert np.linalg.norm(roof - [0.0, 120.0]) < np.linalg.norm(beside - [0.0, 120.0])
    assert ctg(roof) > ctg(beside)


def test_points_off_the_raster_add_their_distance_to_it():
    ctg = CostToGo(np.array([0.0, 0.0]), [], SPACING, 10.0, np.array([0.0, 0.0]))
    far = float(ctg(np.array([500.0, 0.0])))
    assert 500.0 - 1e-6 <= far <= 500.0 + SPACING
