"""The HAPS JSBSim model: loads cleanly, trims at 18, 20 and 21 km at EAS 8 m/s, flies hands-off."""

import math

import pytest

from aircraft import airframe_dir
from sim.core.constants import FT
from sim.geodesy import GeoPoint
from sim.jsbsim_plant import InitialConditions, JSBSimPlant

ORIGIN = GeoPoint(47.0, 8.0, 0.0)
STALL_ALPHA_DEG = 9.0  # CLmax of the CL(alpha) table in haps.xml
POWER_MAX_W = 2 * 1500.0
# (altitude MSL [m], TAS [m/s] for EAS 8 m/s in the ISA)
CRUISE = [(18_000.0, 25.4), (20_000.0, 29.7), (21_000.0, 32.2)]


def trimmed(alt_m: float, tas_mps: float) -> JSBSimPlant:
    plant = JSBSimPlant("haps", 1.0 / 120.0, ORIGIN, airframe_dir("haps"))
    plant.initialise(InitialConditions(GeoPoint(ORIGIN.lat_deg, ORIGIN.lon_deg, alt_m), tas_mps=tas_mps))
    plant.trim()
    return plant


def test_model_loads_without_warnings():
    plant = JSBSimPlant("haps", 1.0 / 120.0, ORIGIN, airframe_dir("haps"))
    assert plant.warnings == []  # JSBSim warnings caught by the plant's quiet logger
    assert plant["inertia/weight-lbs"] * 0.45359237 == pytest.approx(75.0, rel=1e-3)
    assert plant["metrics/bw-ft"] * FT == pytest.approx(25.0)
    assert plant["metrics/Sw-sqft"] * FT**2 == pytest.approx(20.0)
    assert plant.fdm.get_propulsion().get_num_engines() == 2


@pytest.mark.parametrize("alt_m,tas_mps", CRUISE)
def test_full_trim_at_cruise(alt_m, tas_mps):
    p = trimmed(alt_m, tas_mps)
    s = p.truth()
    # residual accelerations of JSBSim's full trim (translational ft/s^2, rotational rad/s^2)
    for axis in ("udot", "vdot", "wdot"):
        assert abs(p[f"accelerations/{axis}-ft_sec2"]) < 1e-2, axis
    for axis in ("pdot", "qdot", "rdot"):
        assert abs(p[f"accelerations/{axis}-rad_sec2"]) < 1e-3, axis
    assert s.eas_mps == pytest.approx(8.0, abs=0.1)
    assert s.tas_mps == pytest.approx(tas_mps, abs=0.05)
    alpha_deg = math.degrees(s.alpha_rad)
    assert 2.0 < alpha_deg < STALL_ALPHA_DEG - 3.0
    assert abs(s.roll) < math.radians(0.5) and abs(s.beta_rad) < math.radians(0.5)
    thr = [p[f"fcs/throttle-cmd-norm[{i}]"] for i in range(2)]
    assert thr[0] == pytest.approx(thr[1])
    assert 0.0 < thr[0] < 1.0
    # electric_engine: shaft power = throttle x rated power; level flight needs ~0.7-1 kW here
    power_w = sum(p[f"propulsion/engine[{i}]/power-hp"] for i in range(2)) * 745.69987
    assert power_w == pytest.approx(thr[0] * POWER_MAX_W, rel=1e-3)
    assert 600.0 < power_w < 1100.0
    assert abs(p["fcs/elevator-pos-norm"]) < 0.3


def test_power_grows_with_altitude_at_constant_eas():
    """Same EAS, same CL and drag: power D V scales with TAS."""
    thr = [trimmed(alt, tas)["fcs/throttle-cmd-norm[0]"] for alt, tas in CRUISE]
    assert thr[0] < thr[1] < thr[2]
    assert thr[2] / thr[0] == pytest.approx(CRUISE[2][1] / CRUISE[0][1], rel=0.05)


def test_hands_off_from_trim_stays_near_trim():
    """60 s without autopilot: the longitudinal modes are stable; the slowly divergent spiral
    mode stays small over this time."""
    p = trimmed(20_000.0, 29.7)
    p.step(60 * 120)
    s = p.truth()
    assert abs(s.alt_msl_m - 20_000.0) < 20.0
    assert abs(s.tas_mps - 29.7) < 1.0
    assert abs(s.roll) < math.radians(5.0)
