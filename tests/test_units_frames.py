"""Quantity parsing and frame conversions."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from sim.core.frames import enu_to_ned, euler_to_quat, ned_to_enu
from sim.geodesy import GeoPoint, LocalLevelFrame, geodetic_to_ned, ned_to_geodetic
from sim.units import to_si


@pytest.mark.parametrize(
    "value,dim,si",
    [
        ("18 km", "length", 18000.0),
        (59000, "length", 59000.0),
        ("1000 ft", "length", 304.8),
        ("50 kt", "speed", 50 * 1852 / 3600),
        ("90 km/h", "speed", 25.0),
        (90, "angle", math.pi / 2),
        ("1 rad", "angle", 1.0),
        ("2.5 h", "time", 9000.0),
        ("75 min", "time", 4500.0),
        ("-1e3 m", "length", -1000.0),
    ],
)
def test_quantities(value, dim, si):
    assert to_si(value, dim) == pytest.approx(si)


@pytest.mark.parametrize(
    "value,dim,msg",
    [
        ("26 km", "speed", "wrong unit: 'km' is a length"),
        ("3 parsec", "length", "unknown unit"),
        (True, "length", "boolean"),
        ("fast", "speed", "expected a speed"),
        ("inf m", "length", "expected"),
    ],
)
def test_bad_quantities(value, dim, msg):
    with pytest.raises(ValueError, match=msg):
        to_si(value, dim)


ORIGIN = GeoPoint(47.0, 8.0, 400.0)


@given(n=st.floats(-1e5, 1e5), e=st.floats(-1e5, 1e5), d=st.floats(-3e4, 1e3))
def test_ned_geodetic_round_trip_within_a_centimetre(n, e, d):
    p = np.array([n, e, d])
    back = geodetic_to_ned(*ned_to_geodetic(p, ORIGIN), ORIGIN)
    assert np.allclose(back, p, atol=0.01)


def test_local_level_down_is_altitude_difference():
    # 20 km north at the origin's altitude: D stays 0 (a tangent plane would say about -31 m)
    p = geodetic_to_ned(47.0 + 20_000 / 111_200, 8.0, 400.0, ORIGIN)
    assert p[2] == 0.0 and p[0] == pytest.approx(20_000, rel=2e-3)


def test_enu_ned_swap_and_quaternion():
    v = np.array([1.0, 2.0, 3.0])
    assert np.allclose(ned_to_enu(v), [2.0, 1.0, -3.0])
    assert np.allclose(enu_to_ned(ned_to_enu(v)), v)
    # yaw 90 deg: body x points east
    w, x, y, z = euler_to_quat(0.0, 0.0, math.pi / 2)
    assert (
        (x, y) == pytest.approx((0.0, 0.0))
        and z == pytest.approx(math.sqrt(0.5))
        and w == pytest.approx(math.sqrt(0.5))
    )


@given(
    lat=st.floats(-80, 80),
    lon=st.floats(-179, 179),
    n=st.floats(-2e5, 2e5),
    e=st.floats(-2e5, 2e5),
    h=st.floats(-400, 30000),
)
def test_fast_local_frame_equals_the_array_conversion(lat, lon, n, e, h):
    origin = GeoPoint(lat, lon, 350.0)
    la, lo, al = ned_to_geodetic(np.array([n, e, 350.0 - h]), origin)
    fast = LocalLevelFrame(origin).ned(float(la), float(lo), float(al))
    assert np.allclose(fast, geodetic_to_ned(la, lo, al, origin), atol=1e-6)
