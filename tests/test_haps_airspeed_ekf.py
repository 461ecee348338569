"""The HAPS holds airspeed and altitude on the default EKF estimator (noisy, biased pitot and
baro), at 18-21 km, in calm air and in a 15 m/s crosswind; read from the MCAP's truth."""

from __future__ import annotations

import numpy as np
import pytest
from test_wind import _haps_leg, _run, _truth

pytestmark = pytest.mark.closed_loop


def _fly(
    tmp_path, altitude: float, tas0: float, tas: float, crosswind: float, seed: int, duration: float, after: float
):
    data = _haps_leg(altitude, tas0, duration, {"east": crosswind}, estimator="ekf")
    data["seed"] = seed
    data["vehicle"][0]["mission"]["cruise_speed"] = tas
    data["vehicle"][0]["mission"]["waypoints"] = [{"north": 100000.0, "east": 0.0, "altitude": altitude}]
    return _truth(_run(tmp_path, data, f"s{seed}"), "haps", after)


# (altitude [m], TAS [m/s], crosswind [m/s]): the crosswind at the lowest TAS (18 km) and in
# the thinnest air (21 km) in CI, the others with ``-m slow``; calm 21 km is also the step test's
CASES = [
    (18000.0, 26.0, 15.0),
    (21000.0, 30.0, 15.0),
    *(
        pytest.param(*case, marks=pytest.mark.slow)
        for case in [(18000.0, 26.0, 0.0), (20000.0, 30.0, 0.0), (20000.0, 30.0, 15.0), (21000.0, 30.0, 0.0)]
    ),
]


@pytest.mark.parametrize(("altitude", "tas", "crosswind"), CASES)
@pytest.mark.parametrize("seed", [3, *(pytest.param(s, marks=pytest.mark.slow) for s in range(20) if s != 3)])
def test_straight_flight_holds_airspeed_and_altitude_on_the_ekf(tmp_path, altitude, tas, crosswind, seed):
    """Seed 3 of two cases in CI; every case on the other 19 seeds with ``-m slow``
    (docs/environment.md)."""
    s = _fly(tmp_path, altitude, tas, tas, crosswind, seed=seed, duration=300.0, after=60.0)
    assert np.abs(s["tas_mps"] - tas).max() < 2.0  # measured: 0.33-0.45 m/s (seed 3)
    assert np.abs(s["alt_msl_m"] - altitude).max() < 50.0  # measured: 1.6-1.8 m (seed 3)


def test_airspeed_step_at_21_km_has_no_mean_error_on_the_ekf(tmp_path):
    s = _fly(tmp_path, 21000.0, 33.0, 30.0, 0.0, seed=3, duration=600.0, after=300.0)  # after the change settles
    # pitot noise through the TECS clamps gave +3.46 m/s before the autopilot low-passed it
    assert abs(float(np.mean(s["tas_mps"] - 30.0))) < 0.3  # measured: +0.02 m/s


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(20))
def test_airspeed_step_at_21_km_across_seeds(tmp_path, seed):
    s = _fly(tmp_path, 21000.0, 33.0, 30.0, 15.0, seed=seed, duration=900.0, after=300.0)
    assert abs(float(np.mean(s["tas_mps"] - 30.0))) < 0.3
    assert np.abs(s["tas_mps"] - 30.0).max() < 2.0 and np.abs(s["alt_msl_m"] - 21000.0).max() < 50.0
