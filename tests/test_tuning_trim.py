"""Trim over the envelope: JSBSim's and the casadi trim of the HAPS agree, residuals below
tolerance at every trimmable point, failures carry a reason; multirotor hover/forward trim."""

import math

import pytest

from sim.tuning import report, trim_haps, trim_quad

ALTS = (16_000.0, 18_000.0, 20_000.0, 21_000.0)
SPEEDS = (22.0, 28.0, 34.0)


@pytest.fixture(scope="module")
def haps_rows():
    return trim_haps.envelope(ALTS, SPEEDS, check_in_jsbsim=False)


def test_haps_residuals_below_tolerance_across_envelope(haps_rows):
    ok = [r for r in haps_rows if r.ok]
    assert len(ok) >= 16  # 12 points x 2 methods, minus the sub-stall ones at 20-21 km, 22 m/s
    for r in ok:
        if r.method == "jsbsim":
            assert r.residual_acc < trim_haps.TOL_ACC and r.residual_rot < trim_haps.TOL_ROT, r
        else:
            assert r.residual_model < 1e-8, r


def test_haps_jsbsim_and_casadi_trims_agree(haps_rows):
    pairs = {}
    for r in haps_rows:
        pairs.setdefault((r.alt_m, r.tas_mps), {})[r.method] = r
    compared = 0
    for (h, v), p in pairs.items():
        j, c = p["jsbsim"], p["casadi"]
        assert j.ok == c.ok, (h, v, j.reason, c.reason)  # same verdict, both with a reason
        if j.ok:
            compared += 1
            assert c.alpha_deg == pytest.approx(j.alpha_deg, abs=0.02)
            assert c.elevator_norm == pytest.approx(j.elevator_norm, abs=0.002)
            assert c.throttle == pytest.approx(j.throttle, rel=0.005)
            assert c.prop_rpm == pytest.approx(j.prop_rpm, rel=0.002)
        else:
            assert j.reason and c.reason
    assert compared >= 8


def test_haps_sub_stall_point_is_reported_not_hidden(haps_rows):
    bad = [r for r in haps_rows if r.alt_m == 21_000.0 and r.tas_mps == 22.0]
    assert bad and not any(r.ok for r in bad)
    assert any("stall" in r.reason for r in bad)
    md = report.markdown(haps_rows, "t")
    assert "21000 m, 22.0 m/s" in md and "Failures" in md


def test_casadi_trim_is_a_jsbsim_trim():
    """JSBSim's own accelerations at the casadi solution are (near) zero: the surrogate is the
    same aircraft. Tolerance covers the Coriolis acceleration the flat-earth surrogate ignores."""
    pt = trim_haps.casadi_trim(20_000.0, 29.7, check_in_jsbsim=True)
    assert pt.ok, pt.reason
    assert pt.residual_acc < trim_haps.TOL_ACC_CROSS and pt.residual_rot < trim_haps.TOL_ROT


@pytest.mark.parametrize("speed", [0.0, 10.0, 20.0])
def test_quadrotor_trim(speed):
    pt = trim_quad.quad_trim(100.0, speed)
    assert pt.ok, pt.reason
    assert pt.residual_acc < trim_quad.TOL_ACC and pt.residual_rot < trim_quad.TOL_ROT
    if speed == 0.0:
        assert pt.throttle == pytest.approx(0.408, abs=0.005)  # model card: hover throttle 0.408
        assert abs(pt.pitch_deg) < 1e-3
    else:  # nose down into the wind, tilt balancing the drag: tan(theta) = D / W (CD 1, 0.0161 m^2)
        rho = 1.2133
        drag = 0.5 * rho * speed**2 * 0.0161
        assert -pt.pitch_deg == pytest.approx(math.degrees(math.atan2(drag, 1.4 * 9.80665)), abs=0.3)


def test_quadrotor_trim_flies_steady_in_jsbsim():
    """Fly the hover trim open loop (FCS bypassed) for 1 s: it stays put."""
    pt = trim_quad.quad_trim(100.0, 0.0)
    prob = trim_quad.QuadTrimProblem(100.0, 0.0)
    plant = prob.plant
    plant.set_many({f"ap/motor-health[{i}]": pt.throttle for i in range(4)})
    plant["forces/hold-down"] = 1.0
    plant.step(240)
    plant["forces/hold-down"] = 0.0
    plant.step(240)
    s = plant.truth()
    assert abs(s.vel_ned[2]) < 0.01 and abs(s.alt_msl_m - 100.0) < 0.01


def test_report_files(tmp_path, haps_rows):
    paths = report.write_all(haps_rows, tmp_path, "trim_haps", "HAPS")
    assert paths["png"].stat().st_size > 10_000
    assert paths["csv"].read_text().count("\n") == len(haps_rows) + 1
