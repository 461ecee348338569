"""Avoidance Grid geometry (spec §3, T-GR-1..3, T-LI-3) and property tests of the cell lookup."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from avoidance.reachset.config import GridConfig
from avoidance.reachset.frames import GridPose, from_polar, to_polar
from avoidance.reachset.grid import AvoidanceGrid

GRID = AvoidanceGrid()


def test_default_grid_has_350_cells():
    assert GRID.n_cells == 350 and GRID.shape == (10, 7, 5)
    assert GRID.steps[0] == pytest.approx(1.0)
    assert np.degrees(GRID.steps[1]) == pytest.approx(12.857, abs=1e-3) and np.degrees(GRID.steps[2]) == pytest.approx(
        12.0
    )
    assert GRID.volume.sum() == pytest.approx(1000 / 3 * np.pi / 2 * 1.0, rel=1e-12)
    mid = GRID.cell_index_polar(np.array([[9.5, 0.0, 0.0]]))[0]
    assert GRID.volume[mid] == pytest.approx(4.2377, abs=1e-4)


def test_boundary_membership():
    layer = lambda d: GRID.layer[GRID.cell_index(np.array([[d, 0.0, 0.0]]))[0]]  # noqa: E731
    assert layer(1.0) == 0 and layer(1.0 + 1e-6) == 1 and layer(10.0) == 9
    assert GRID.cell_index(np.array([[0.0, 0.0, 0.0], [10.0 + 1e-6, 0, 0]])).tolist() == [-1, -1]
    on_edge = GRID.cell_index_polar(np.array([[5.0, -np.pi / 4, 0.0], [5.0, np.pi / 4, 0.0]]))
    assert on_edge[0] == -1 and on_edge[1] >= 0


def test_area_formula_outer_face():
    c = GRID.cell_index_polar(np.array([[9.5, 0.0, 0.0]]))
    assert GRID.face_area(np.array([10.0]), c)[0] == pytest.approx(4.6912, abs=1e-4)


def test_outer_cells_and_zones():
    ijk = GRID.ijk0
    assert GRID.outer[(ijk[:, 0] == 9)].all() and GRID.outer[(ijk[:, 1] == 0)].all()
    inner = (ijk[:, 0] < 9) & (ijk[:, 1] > 0) & (ijk[:, 1] < 6) & (ijk[:, 2] > 0) & (ijk[:, 2] < 4)
    assert not GRID.outer[inner].any()
    assert set(GRID.zone[GRID.layer < 3]) == {0} and set(GRID.zone[GRID.layer >= 7]) == {2}


def test_scaled_grid_for_longer_movements():
    g = AvoidanceGrid(GridConfig().scaled(26.0))
    assert g.range == 260.0 and g.n_cells == 350


def test_volume_samples_cover_every_cell():
    pts, cells, w = GRID.volume_samples
    np.testing.assert_allclose(np.bincount(cells, weights=w), GRID.volume)
    np.testing.assert_array_equal(GRID.cell_index(pts), cells)


def test_pose_round_trip_and_heading():
    pose = GridPose.from_ned(np.array([10.0, 5.0, -3.0]), np.pi / 2)  # heading east
    np.testing.assert_allclose(pose.ned_to_lcf(np.array([10.0, 7.0, -3.0])), [2.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(
        pose.ned_to_lcf(np.array([12.0, 5.0, -4.0])), [0.0, 2.0, 1.0], atol=1e-12
    )  # north = left
    p = np.array([1.0, -2.0, 3.0])
    np.testing.assert_allclose(pose.lcf_to_ned(pose.ned_to_lcf(p)), p, atol=1e-12)


inside = st.tuples(
    st.floats(1e-6, 10.0), st.floats(-np.pi / 4 + 1e-6, np.pi / 4), st.floats(-np.pi / 6 + 1e-6, np.pi / 6)
)


@settings(max_examples=300, deadline=None)
@given(inside)
def test_every_point_inside_maps_to_exactly_the_cell_containing_it(dtp):
    p = from_polar(np.array([dtp]))
    c = GRID.cell_index(p)[0]
    assert c >= 0
    q = to_polar(p)[0]
    tol = 1e-7
    containing = np.flatnonzero(np.all((GRID.lower - tol < q) & (q <= GRID.upper + tol), axis=1))
    strictly = np.flatnonzero(np.all((GRID.lower + tol < q) & (q < GRID.upper - tol), axis=1))
    assert c in containing and len(strictly) <= 1 and (len(strictly) == 0 or strictly[0] == c)


@settings(max_examples=200, deadline=None)
@given(st.floats(-30, 30), st.floats(-30, 30), st.floats(-30, 30))
def test_points_outside_map_to_no_cell(x, y, z):
    p = np.array([[x, y, z]])
    d, th, ph = to_polar(p)[0]
    outside = d > 10.0 + 1e-6 or abs(th) > np.pi / 4 + 1e-6 or abs(ph) > np.pi / 6 + 1e-6 or d == 0.0
    if outside:
        assert GRID.cell_index(p)[0] == -1
