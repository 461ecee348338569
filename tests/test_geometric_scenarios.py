"""Geometric avoider, open loop on the thesis scenarios (spec §7.5, reconstructed geometries §7.6
13–15). Thesis collision rules (swept) unless stated; ENU z-up, reference along +x (S1, S3)."""

from __future__ import annotations

import numpy as np
import pytest

from avoidance.geometric.avoider import Status
from avoidance.geometric.config import GeometricConfig
from sim.testbeds.geometric_encounters import scenario1, scenario2, scenario3

THESIS = GeometricConfig.thesis()
S1_CFG = GeometricConfig.thesis(path_types=("symmetric",))


def _chosen(res):
    c, k = res.candidates, res.chosen
    return c, k, c.points[k, : c.n_pts[k]]


@pytest.mark.parametrize("cfg", [S1_CFG, THESIS], ids=["symmetric", "both"])
def test_scenario1_collision_angle(cfg):
    widths = {}
    for radius in (1.0, 1.5):
        res = scenario1(160.0, radius).plan(cfg)
        assert res.status is Status.AVOID
        c, k, _ = _chosen(res)
        assert c.theta[k] == 0.0 and c.alpha[k] == pytest.approx(0.0)  # horizontal plane
        assert abs(c.omega[k]) == pytest.approx(3.2 * radius)
        widths[radius] = abs(c.omega[k])
    assert widths[1.5] > widths[1.0]  # wider for the larger threat
    res = scenario1(174.0, 1.5).plan(cfg)
    assert res.status is Status.NO_SOLUTION and not res.available.any()


def test_scenario1_174_has_a_solution_with_the_time_synchronised_check():
    """The thesis' over-correction (§5.2): comparing positions at equal times frees the rejoin."""
    assert scenario1(174.0, 1.5).plan(GeometricConfig(start_shift_s=0.0)).status is Status.AVOID


@pytest.mark.parametrize("cfg", [THESIS, GeometricConfig(start_shift_s=0.0)], ids=["swept", "timed"])
def test_scenario2_climbs_over(cfg):
    res = scenario2().plan(cfg)
    assert res.status is Status.AVOID
    c, k, p = _chosen(res)
    assert np.degrees(c.theta[k]) == pytest.approx(90.0) and c.omega[k] > 0
    d = np.array([np.cos(np.radians(20)), 0, np.sin(np.radians(20))])
    height_over_reference = p[:, 2] - (p @ d) * d[2]
    assert height_over_reference.min() >= -1e-9 and height_over_reference.max() > 3.0
    descend_first = np.flatnonzero((c.theta == c.theta[k]) & (c.kind == c.kind[k]) & np.isclose(c.omega, -c.omega[k]))[
        0
    ]
    assert res.costs.normalised["cmo"][descend_first] > res.costs.normalised["cmo"][k]


@pytest.mark.parametrize("cfg", [THESIS, GeometricConfig(start_shift_s=0.0)], ids=["swept", "timed"])
def test_scenario3_static_descends_moving_goes_lateral_and_costs_more(cfg):
    a = scenario3(moving_main=False).plan(cfg)
    b = scenario3(moving_main=True).plan(cfg)
    assert a.status is b.status is Status.AVOID
    _ca, ka, pa = _chosen(a)
    assert pa[len(pa) // 2, 2] < -3.0 and np.all(pa[:, 2] <= 1e-9)  # descends first (below p_c)
    assert not b.available[ka]  # (a)'s choice is unavailable in (b)
    cb, kb, pb = _chosen(b)
    assert cb.alpha[kb] == pytest.approx(0.0) and abs(cb.omega[kb]) == pytest.approx(1.6 * 2.0)
    assert np.allclose(pb[:, 2], 0.0, atol=1e-9)  # horizontal, lateral
    assert b.cost > a.cost
    # the reconstructed geometry is point-symmetric about p_c: the mirror image (left / right)
    # ties to 1e-12, so which side wins is decided by rounding, not by the scenario
    left = np.flatnonzero((cb.kind == cb.kind[kb]) & (cb.theta == 0) & np.isclose(cb.omega, -cb.omega[kb]))[0]
    assert b.available[left] and b.costs.total[left] == pytest.approx(b.cost, abs=1e-12)


@pytest.mark.parametrize("cfg", [THESIS, GeometricConfig(start_shift_s=0.0)], ids=["swept", "timed"])
def test_scenario3_moving_goes_to_the_side_away_from_the_diagonal_threats(cfg):
    """With the diagonal threats shifted sideways the tie is broken by the scene: the moving case
    takes the level path on the far side (left for a shift to the right, as in the thesis), still
    costlier than the static case, and its mirror is strictly costlier."""
    for shift, side in ((-1.0, 1.0), (1.0, -1.0)):
        a = scenario3(False, shift).plan(cfg)
        b = scenario3(True, shift).plan(cfg)
        assert a.status is b.status is Status.AVOID
        _, _, pa = _chosen(a)
        assert pa[len(pa) // 2, 2] < -2.0 and np.all(pa[:, 2] <= 1e-9)  # static: descends first
        cb, kb, pb = _chosen(b)
        assert np.allclose(pb[:, 2], 0.0, atol=1e-9) and np.sign(pb[len(pb) // 2, 1]) == side
        assert b.cost > a.cost
        mirror = np.flatnonzero((cb.kind == cb.kind[kb]) & (cb.theta == 0) & np.isclose(cb.omega, -cb.omega[kb]))[0]
        assert not b.available[mirror] or b.costs.total[mirror] > b.cost + 1e-4
