"""The log tick's cheaper arithmetic gives the bits of the numpy forms it replaced (the logs and
metrics must not change): leg progress on Python floats, the multirotor cross-track without
``np.linalg.norm``, the 3-sigma bounds in one call, setpoint rows by one field lookup."""

from __future__ import annotations

import math

import numpy as np
import pytest

from guidance.multirotor_follower import MultirotorPlanFollower
from guidance.path import leg_progress
from sim.estimation.ins_model import three_sd, three_sds
from sim.log_rows import COMMANDS, FIXED_WING_SETPOINT, MULTIROTOR_SETPOINT, SIGMA_INPUTS, flatten, record_values

RNG = np.random.default_rng(19)


def _points(n: int) -> np.ndarray:
    """(n, 3) NED points [m] over many magnitudes (subtractions that round differently)."""
    return RNG.normal(size=(n, 3)) * 10.0 ** RNG.uniform(-3, 5, size=(n, 1))


def test_leg_progress_is_the_numpy_scalar_arithmetic():
    for pos, a, b in zip(_points(300), _points(300), _points(300), strict=True):
        dn, de = float(b[0] - a[0]), float(b[1] - a[1])
        pn, pe = float(pos[0] - a[0]), float(pos[1] - a[1])
        length = math.hypot(dn, de)
        un, ue = dn / length, de / length
        got = leg_progress(pos, a, b)
        assert (got.along_m, got.cross_m, got.length_m) == (pn * un + pe * ue, -pn * ue + pe * un, length)
        assert (got.to_end_m, got.bearing_rad) == (math.hypot(dn - pn, de - pe), math.atan2(de, dn))
    assert leg_progress(np.array([3.0, 4.0, 0.0]), np.zeros(3), np.zeros(3)).to_end_m == 5.0


def test_multirotor_cross_track_is_norms_arithmetic():
    fol = MultirotorPlanFollower(5.0, 2.0, 1.0, 0.5)
    for pos, a, w in zip(_points(300), _points(300), _points(300), strict=True):
        u = w / np.linalg.norm(w)
        fol._leg_au = (a, u)
        ap = pos - a
        assert fol.track_error(pos) == float(np.linalg.norm(ap - u * float(ap @ u)))


def test_three_sds_is_three_sd_of_each():
    v = [0.0, 1e-12, 2.5, 4e6, -1.0]
    got = three_sds(v)
    assert got[:4] == [3.0 * float(np.sqrt(x)) for x in v[:4]] == [three_sd(x) for x in v[:4]]
    assert math.isnan(got[4]) and math.isnan(three_sd(-1.0))


@pytest.mark.parametrize("columns", [FIXED_WING_SETPOINT[1:], MULTIROTOR_SETPOINT[1:], MULTIROTOR_SETPOINT[:1]])
def test_record_values_is_flatten(columns):
    d = {name: ([0.5 * k, -1.0, 2.0][:width] if width else 1.5 * k) for k, (name, width) in enumerate(columns)}
    assert record_values(columns)(d) == flatten(columns, d)[0]


@pytest.mark.parametrize("columns", [COMMANDS, SIGMA_INPUTS])
def test_record_values_refuses_maps_and_nested_fields(columns):
    with pytest.raises(ValueError, match="map or a nested field"):
        record_values(columns)
