"""Geometric avoider: candidate geometry, counts, frames, velocity profile (spec §2, §3.2, §7.6 1–4)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from avoidance.geometric.avoider import Status
from avoidance.geometric.config import GeometricConfig
from avoidance.geometric.frames import plane_angles, plane_elevation, uav_frame
from avoidance.geometric.generation import SIMPLE, SYMMETRIC, cubic_shape, generate_candidates, omega_grid, path_shape
from avoidance.geometric.kinematics import capped_velocity, path_kinematics
from avoidance.geometric.threats import Threat
from sim.testbeds.geometric_encounters import Encounter


@pytest.mark.parametrize("dx, w", [(10.0, 3.2), (7.5, -4.8), (4.0, 1.6)])
def test_cubic_identities(dx, w):
    h = 1e-6 * dx
    y = lambda x: cubic_shape(dx, np.array([w]), np.atleast_1d(x))[0]  # noqa: E731
    slope = lambda x: (y(x + h) - y(x - h))[0] / (2 * h)  # noqa: E731
    assert y(0.0)[0] == 0 and y(dx)[0] == pytest.approx(w) and y(1.5 * dx)[0] == pytest.approx(0, abs=1e-12)
    assert slope(0.0) == pytest.approx(0, abs=1e-6) and slope(dx) == pytest.approx(0, abs=1e-6)
    assert slope(1.5 * dx) == pytest.approx(-4.5 * w / dx, rel=1e-6)


def test_omega_grid_and_path_counts():
    assert np.allclose(omega_grid(1.0, 4), [-3.2, -1.6, 1.6, 3.2])
    assert np.allclose(sorted(np.abs(omega_grid(1.0, 12))), np.repeat([16 / 15, 1.6, 32 / 15, 8 / 3, 3.2], 2))
    assert np.degrees(plane_angles(3)) == pytest.approx([0, 45, 90, 135])
    for n_l, n in [(4, 3), (4, 1), (4, 5)]:
        c = generate_candidates(
            np.zeros(3), [1, 0, 0], 10.0, 1.0, GeometricConfig(l=n_l, n_planes=n, path_types=("simple",))
        )
        assert len(c) == n_l * (n + 1)  # L = l(n+1), exact for l = 4
    both = generate_candidates(np.zeros(3), [1, 0, 0], 10.0, 1.0, GeometricConfig())
    assert len(both) == 32 and set(both.n_pts) == {16, 21}
    # l = 12 keeps 10 offsets per plane, not l: the thesis count holds only for l = 4
    assert (
        len(generate_candidates(np.zeros(3), [1, 0, 0], 10.0, 1.0, GeometricConfig(l=12, path_types=("simple",)))) == 40
    )


@pytest.mark.parametrize("x_dir", [[1, 0, 0], [0.3, -0.8, 0.4], [0.0, 0.0, 1.0]])
def test_peak_offset_above_threat_and_tangential_ends(x_dir):
    """Each candidate peaks |ω| from the reference exactly abreast of the threat centre, leaves
    the reference tangentially, and symmetric paths also rejoin tangentially."""
    cfg = GeometricConfig()
    start, dx = np.array([1.0, 2.0, 3.0]), 10.0
    c = generate_candidates(start, x_dir, dx, 1.5, cfg)
    x_hat = c.frame[:, 0]
    centre = start + dx * x_hat
    for k in range(len(c)):
        p = c.points[k, : c.n_pts[k]]
        rel = p - start
        along = rel @ x_hat
        lateral = rel - along[:, None] * x_hat
        peak = np.argmax(np.linalg.norm(lateral, axis=1))
        assert np.allclose(p[peak] - lateral[peak], centre) and np.linalg.norm(lateral[peak]) == pytest.approx(
            abs(c.omega[k])
        )
        first = (p[1] - p[0]) / np.linalg.norm(p[1] - p[0])
        assert first @ x_hat > 0.99  # O(h²) chord of a zero slope
        assert np.linalg.norm(lateral[-1]) < 1e-9  # rejoins the reference line
        if c.kind[k] == SYMMETRIC:
            last = (p[-1] - p[-2]) / np.linalg.norm(p[-1] - p[-2])
            assert last @ x_hat > 0.99 and along[-1] == pytest.approx(2 * dx)
        else:
            assert along[-1] == pytest.approx(1.5 * dx)


def test_frame_and_plane_elevation():
    f = uav_frame([1.0, 0.0, 0.0])
    assert np.allclose(f, np.eye(3))  # ŷ = ẑ×x̂ is left, ẑ up
    assert np.allclose(f.T @ f, np.eye(3)) and np.linalg.det(uav_frame([0, 0, -1])) == pytest.approx(1)
    a = plane_elevation(f, plane_angles(3))
    assert np.degrees(a) == pytest.approx([0, 45, 90, 45])
    climb = uav_frame([np.cos(0.3), 0, np.sin(0.3)])
    assert plane_elevation(climb, np.array([0.0]))[0] == pytest.approx(0.3)


def test_roc_cap_test_vector_and_descent():
    assert np.allclose(capped_velocity(np.array([0.6, 0, 0.8]), 5.0, 3.0), [2.25, 0, 3.0])
    assert np.allclose(capped_velocity(np.array([0.6, 0, -0.8]), 5.0, 3.0), [2.25, 0, -3.0])
    assert np.allclose(capped_velocity(np.array([1.0, 0, 0]), 5.0, 3.0), [5, 0, 0])


def test_kinematics_padding_and_times():
    c = generate_candidates(np.zeros(3), [1, 0, 0], 10.0, 1.0, GeometricConfig())
    kin = path_kinematics(c.points, c.n_pts, 5.0, 3.0)
    assert np.all(np.abs(kin.seg_vel[..., 2]) <= 3.0 + 1e-12)
    k = int(np.flatnonzero(c.n_pts == 16)[0])
    assert np.all(kin.seg_dt[k, 15:] == 0) and np.allclose(kin.seg_vel[k, 15:], kin.seg_vel[k, 14])
    horizontal = int(np.flatnonzero((c.theta == 0) & (c.n_pts == 16))[0])
    length = np.linalg.norm(np.diff(c.points[horizontal, :16], axis=0), axis=1).sum()
    assert kin.T[horizontal] == pytest.approx(length / 5.0)


def test_symmetric_shape_mirrors_about_peak():
    x, y = path_shape(8.0, np.array([2.0, -3.0]), SYMMETRIC, 0.1)
    assert np.allclose(x + x[::-1], 16.0) and np.allclose(y, y[:, ::-1]) and x[10] == 8.0
    _xs, ys = path_shape(8.0, np.array([2.0]), SIMPLE, 0.1)
    assert np.allclose(y[0, :11], ys[0, :11])


def test_invalid_geometry_inputs():
    with pytest.raises(ValueError):
        omega_grid(-1.0, 4)
    with pytest.raises(ValueError):
        generate_candidates(np.zeros(3), [1, 0, 0], -2.0, 1.0, GeometricConfig())
    with pytest.raises(ValueError):
        uav_frame([0, 0, 0])
    with pytest.raises(ValueError):
        Threat("bad", np.zeros(3), np.zeros(3), -1.0)
    with pytest.raises(ValueError):
        GeometricConfig(path_types=("spiral",))
    with pytest.raises(ValueError):
        GeometricConfig(weights=(0.5, 0.5, 0.5))


def test_two_and_a_half_r_rule():
    enc = Encounter(np.zeros(3), np.array([1.0, 0, 0]), (Threat("m", np.array([7.4, 0, 0]), np.zeros(3), 3.0),))
    assert enc.plan(GeometricConfig()).status is Status.TOO_CLOSE
    enc = Encounter(np.zeros(3), np.array([1.0, 0, 0]), (Threat("m", np.array([7.5, 0, 0]), np.zeros(3), 3.0),))
    assert enc.plan(GeometricConfig()).status is Status.AVOID


unit_vectors = st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda v: np.linalg.norm(v) > 0.2)


@settings(max_examples=40, deadline=None)
@given(
    x_dir=unit_vectors,
    dist=st.floats(8.0, 14.0),
    radius=st.floats(0.5, 2.0),
    others=st.lists(st.tuples(st.floats(0, 25), st.floats(-8, 8), st.floats(-8, 8), st.floats(0.3, 2.5)), max_size=4),
    mode=st.sampled_from(["swept", "timed"]),
)
def test_accepted_paths_clear_every_static_sphere(x_dir, dist, radius, others, mode):
    """Property: every available candidate keeps >= R + r_uav from every static sphere at every
    sample point (and on the segments between them)."""
    cfg = GeometricConfig(dynamic_mode=mode)
    frame = uav_frame(np.array(x_dir))
    spheres = [Threat("main", dist * frame[:, 0], np.zeros(3), radius)]
    spheres += [Threat(f"s{i}", frame @ np.array([a, b, c]), np.zeros(3), r) for i, (a, b, c, r) in enumerate(others)]
    res = Encounter(np.zeros(3), frame[:, 0], tuple(spheres)).plan(cfg)
    if res.status is Status.TOO_CLOSE:
        return
    fine = np.linspace(0, 1, 11)
    for k in np.flatnonzero(res.available):
        p = res.candidates.points[k, : res.candidates.n_pts[k]]
        dense = (p[:-1, None] + (p[1:] - p[:-1])[:, None] * fine[None, :, None]).reshape(-1, 3)
        for s in spheres:
            assert np.linalg.norm(dense - s.p, axis=1).min() >= s.radius + cfg.r_uav - 1e-9


@settings(max_examples=30, deadline=None)
@given(x_dir=unit_vectors, dx=st.floats(3.0, 20.0), radius=st.floats(0.3, 3.0))
def test_candidates_mirror_in_every_plane(x_dir, dx, radius):
    """Property: the ±ω candidates of a plane are mirror images about the reference line, and a
    plane's points lie in it (the symmetric type also mirrors about the peak)."""
    c = generate_candidates(np.zeros(3), x_dir, dx, radius, GeometricConfig())
    x_hat = c.frame[:, 0]
    for k in range(len(c)):
        m = np.flatnonzero((c.kind == c.kind[k]) & (c.theta == c.theta[k]) & np.isclose(c.omega, -c.omega[k]))
        assert m.size == 1
        p, q = c.points[k], c.points[m[0]]
        along_p, along_q = p @ x_hat, q @ x_hat
        assert np.allclose(along_p, along_q, atol=1e-9)
        assert np.allclose(p - along_p[:, None] * x_hat, -(q - along_q[:, None] * x_hat), atol=1e-9)
        normal = c.frame @ np.array([0.0, -np.sin(c.theta[k]), np.cos(c.theta[k])])
        assert np.allclose(p @ normal, 0.0, atol=1e-9)
