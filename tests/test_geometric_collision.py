"""Geometric avoider: vectorised collision checks against loop references, swept vs timed
semantics, covariance inflation, CPA main-threat finder (spec §3.1, §4, §9.5)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from avoidance.geometric.collision import candidate_clearance, segseg_distance
from avoidance.geometric.conflict import find_main_threat
from avoidance.geometric.kinematics import path_kinematics
from avoidance.geometric.threats import Threat, ThreatArrays, inflate

_spec = importlib.util.spec_from_file_location(
    "bench_geometric", Path(__file__).parents[1] / "benchmarks" / "bench_geometric.py"
)
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)

coords = st.floats(-10, 10, allow_nan=False)
points3 = st.tuples(coords, coords, coords).map(np.array)


@settings(max_examples=200, deadline=None)
@given(p1=points3, q1=points3, p2=points3, q2=points3, degenerate=st.sampled_from(["none", "first", "second", "both"]))
def test_segment_distance_matches_scalar_and_dense_sampling(p1, q1, p2, q2, degenerate):
    q1 = p1 if degenerate in ("first", "both") else q1
    q2 = p2 if degenerate in ("second", "both") else q2
    d = float(segseg_distance(p1, q1, p2, q2))
    assert d == pytest.approx(bench._seg_dist(p1, q1, p2, q2), abs=1e-9)
    u = np.linspace(0, 1, 201)
    a, b = p1 + np.outer(u, q1 - p1), p2 + np.outer(u, q2 - p2)
    dense = np.linalg.norm(a[:, None] - b[None], axis=-1).min()
    assert d <= dense + 1e-9
    assert d >= dense - 0.01 * (np.linalg.norm(q1 - p1) + np.linalg.norm(q2 - p2)) - 1e-9


def test_short_segment_touching_the_other_has_zero_distance():
    """A 1e-8 m segment whose far end lies on the other segment is at distance 0 (a segment is
    taken as a point only when its length is exactly zero)."""
    p2, q2 = np.array([0.0, -1.0, 0.0]), np.array([0.0, 1.0, 0.0])
    p1, q1 = np.array([-1e-8, 0.0, 0.0]), np.array([0.0, 0.0, 0.0])
    assert float(segseg_distance(p1, q1, p2, q2)) == pytest.approx(0.0, abs=1e-15)
    assert float(segseg_distance(p2, q2, p1, q1)) == pytest.approx(0.0, abs=1e-15)


@pytest.mark.parametrize("mode", ["swept", "timed"])
def test_vectorised_check_equals_loop_reference(mode):
    """Random paths × random static/moving threats: the batched check and the per-path /
    per-segment / per-threat loop of the benchmark baseline agree on every candidate."""
    rng = np.random.default_rng(3)
    agree = 0
    for trial in range(25):
        K, N, J = 12, int(rng.integers(3, 12)), int(rng.integers(1, 5))
        pts = np.cumsum(rng.normal(0, 1.5, (K, N, 3)) + [2.0, 0, 0], axis=1)
        n_pts = rng.integers(2, N + 1, K)
        pts = np.where(np.arange(N)[None, :, None] < n_pts[:, None, None], pts, pts[np.arange(K), n_pts - 1][:, None])
        kin = path_kinematics(pts, n_pts, 5.0, 3.0)
        threats = [
            Threat(
                f"t{j}",
                rng.uniform(-5, 20, 3),
                rng.normal(0, 2, 3) * (rng.random() < 0.7),
                float(rng.uniform(0.3, 3)),
                float(rng.uniform(0, 0.3)),
            )
            for j in range(J)
        ]
        durations = rng.uniform(0.5, 6.0, J)
        tail = np.array([5.0, 0, 0])
        horizon = float(kin.T.max()) + 2.0
        vec = (
            candidate_clearance(
                pts, kin.seg_vel, kin.tau, kin.seg_dt, ThreatArrays.of(threats), mode, durations, tail, horizon
            ).min(axis=1)
            >= 1.0
        )
        loop = np.array(
            [
                not bench.baseline_collides(
                    pts[k, : n_pts[k]],
                    kin.seg_vel[k],
                    kin.tau[k, : n_pts[k]],
                    threats,
                    durations,
                    mode,
                    1.0,
                    tail,
                    horizon,
                )
                for k in range(K)
            ]
        )
        assert np.array_equal(vec, loop), trial
        agree += vec.sum()
    assert 0 < agree < 25 * 12  # both outcomes exercised


def _crossing(t_cross: float) -> tuple[np.ndarray, ThreatArrays]:
    """UAV along +x at 5 m/s over 0..20 m; a threat crossing its line at x = 10 at τ = t_cross."""
    pts = np.linspace([0, 0, 0], [20, 0, 0], 11)[None]
    th = Threat("x", np.array([10.0, -2.0 * t_cross, 0]), np.array([0.0, 2.0, 0]), 1.0)
    return pts, ThreatArrays.of([th])


def test_swept_is_conservative_and_timed_is_synchronised():
    pts, ta = _crossing(t_cross=3.5)  # the UAV is long past x = 10 by then
    kin = path_kinematics(pts, np.array([11]), 5.0, 3.0)
    args = (pts, kin.seg_vel, kin.tau, kin.seg_dt, ta)
    swept = candidate_clearance(*args, "swept", np.array([4.0]), np.zeros(3), 4.0)
    timed = candidate_clearance(*args, "timed", np.array([4.0]), np.zeros(3), 4.0)
    assert swept[0, 0] < 1.0 <= timed[0, 0]
    pts, ta = _crossing(t_cross=2.0)  # both at x = 10 at τ = 2 s
    timed = candidate_clearance(pts, kin.seg_vel, kin.tau, kin.seg_dt, ta, "timed", np.array([4.0]), np.zeros(3), 4.0)
    assert timed[0, 0] == pytest.approx(-1.0)


def test_timed_check_covers_the_reference_after_rejoin():
    pts = np.linspace([0, 0, 0], [10, 0, 0], 6)[None]
    kin = path_kinematics(pts, np.array([6]), 5.0, 3.0)  # ends at τ = 2 s
    ta = ThreatArrays.of([Threat("late", np.array([20.0, 0, 0]), np.zeros(3), 1.0)])
    tail = np.array([5.0, 0, 0])
    clear = [
        candidate_clearance(pts, kin.seg_vel, kin.tau, kin.seg_dt, ta, "timed", np.zeros(1), tail, h)[0, 0]
        for h in (2.5, 4.0)
    ]
    assert clear[0] > 1.0 and clear[1] < 0.0


def test_inflation_from_covariance():
    cov = np.diag([4.0, 1.0, 1.0])
    assert inflate(1.0, cov, None, 0.0, 3.0) == (1.0, 0.0)
    r, g = inflate(1.0, cov, np.diag([0.25, 0.01, 0.0]), 2.0, 2.0)
    assert r == pytest.approx(1.0 + 2 * 2.0 + 2 * 0.5 * 2.0) and g == pytest.approx(1.0)
    for bad in (np.diag([1.0, -1.0, 1.0]), np.array([[1.0, 2.0, 0], [0, 1, 0], [0, 0, 1]]), np.ones((2, 2))):
        with pytest.raises(ValueError):
            inflate(1.0, bad, None, 2.0, 0.0)


def test_cpa_main_threat_finder():
    start, v = np.zeros(3), np.array([5.0, 0, 0])
    threats = ThreatArrays.of(
        [
            Threat("far_side", np.array([30.0, 8, 0]), np.zeros(3), 1.0),  # misses by 8 m
            Threat("late", np.array([40.0, 0.5, 0]), np.zeros(3), 1.0),  # on course at τ = 8 s
            Threat("crossing", np.array([20.0, -8, 0]), np.array([0.0, 2, 0]), 1.5),  # at (20, 0) at τ = 4 s
        ]
    )
    m = find_main_threat(start, v, threats, 1.0, 10.0)
    assert (
        m.index == 2
        and m.t_cpa == pytest.approx(4.0)
        and np.allclose(m.p_c, [20, 0, 0])
        and m.radius == pytest.approx(1.5)
    )
    only_late = ThreatArrays.of([Threat("late", np.array([40.0, 0.5, 0]), np.zeros(3), 1.0)])
    m = find_main_threat(start, v, only_late, 1.0, 10.0)
    assert m.miss == pytest.approx(0.5) and m.radius == pytest.approx(1.5)  # enclosing sphere on the line (G28)
    assert find_main_threat(start, v, only_late, 1.0, 5.0) is None  # beyond the horizon
