"""The wait bound's grid primitives against the library calls they replace (same values)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from scipy.ndimage import minimum_filter
from shapely.geometry import MultiPolygon, Polygon

from guidance.mptp.waitbound import _inside, disc_minimum


def _disc(reach: float) -> np.ndarray:
    k = math.floor(reach)
    off = np.arange(-k, k + 1)
    return np.hypot(*np.meshgrid(off, off, indexing="ij")) <= reach


@pytest.mark.parametrize("reach", [0.5, 1.0, 1 + math.sqrt(2.0), 2.9, 3.7])
def test_disc_minimum_is_scipys_minimum_filter(reach):
    """Every element, at the edges (constant inf outside) and with inf cells inside; the wait
    bound's own disc is reach 1 + sqrt 2."""
    rng = np.random.default_rng(int(10 * reach))
    disc = _disc(reach)
    for shape in [(1, 1), (2, 9), (17, 5), (40, 33)]:
        a = rng.uniform(0.0, 100.0, shape)
        a[rng.uniform(size=shape) < 0.3] = np.inf
        want = minimum_filter(a, footprint=disc, mode="constant", cval=np.inf)
        assert np.array_equal(disc_minimum(a, disc), want)


def _shapes() -> list:
    square = Polygon([(0, 0), (10, 0), (10, 10), (0, 10)], holes=[[(3, 3), (6, 3), (6, 6), (3, 6)]])
    tilted = shapely.affinity.rotate(Polygon([(0, 0), (7, 1), (9, 8), (2, 11), (4, 5)]), 17.0, origin=(0, 0))
    pair = MultiPolygon([Polygon([(-5, -5), (-1, -5), (-3, -1)]), Polygon([(12, 0), (15, 2), (12, 4)])])
    disc = shapely.Point(4.3, 5.1).buffer(4.0, quad_segs=9)
    return [square, tilted, pair, disc, disc.difference(shapely.Point(4.3, 5.1).buffer(1.5)), Polygon()]


@pytest.mark.parametrize("shape", _shapes())
def test_grid_points_inside_a_shape_are_contains_xy(shape):
    """Strictly inside, as shapely.contains_xy: points on vertices, on vertical and
    horizontal edges and on hole boundaries (the integer grid) are not; holes, several parts
    and columns that run along an edge are handled."""
    for xs, ys in [(np.arange(-6.0, 17.0), np.arange(-6.0, 13.0)), (np.linspace(-6, 16, 97), np.linspace(-6, 12, 83))]:
        gx, gy = np.meshgrid(xs, ys, indexing="ij")
        assert np.array_equal(_inside(shape, xs, ys), shapely.contains_xy(shape, gx, gy))
