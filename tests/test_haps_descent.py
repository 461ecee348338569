"""The HAPS's descent from station to low altitude on the descent EAS schedule, on the EKF.

``scenarios/haps_descent_to_low_altitude.toml``: 18 km -> 1 km (slow, ~9.1 h of flight); the CI
test flies its last 500 m (1.5 km -> 1 km) from the same file. TECS must fly the schedule's
descent EAS at a sink rate within its limit — ``sink_rate_max``, or the drag polar's glide sink at
that EAS where less (aircraft/haps/autopilot.py) — never near the stall, and end holding the
commanded altitude at the mission's cruise speed.
"""

import math

import numpy as np
import pytest

from aircraft.haps.gains import RHO0, HapsGains
from sim.core.constants import STANDARD_GRAVITY
from sim.mcap_read import read_topic

SCENARIO = "haps_descent_to_low_altitude"
TARGET_M = 1000.0
CRUISE_EAS = 10.0  # the scenario's 10.5 m/s TAS at 1 km
STALL_EAS = 6.74  # 1 g, CLmax 1.32 (aircraft/haps/README.md, "Aerodynamics")
ALPHA_CLMAX_DEG = 9.0


def _glide_sink(g: HapsGains, tas_per_eas: np.ndarray) -> np.ndarray:
    """The polar's glide sink [m/s] at the descent EAS, written out independently of TECS."""
    cl = g.mass_kg * STANDARD_GRAVITY / (0.5 * RHO0 * g.descent_eas**2 * g.wing_area_m2)
    return g.descent_eas * tas_per_eas * (g.cd0 + g.k_induced * cl * cl) / cl


def _states(flight) -> dict:
    assert flight.result.status == "duration_elapsed"
    st = [m for _, m in read_topic(flight.path, "/haps/truth/state")]
    return {
        k: np.array([m[k] for m in st])
        for k in ("t", "alt_msl_m", "eas_mps", "tas_mps", "alpha_rad", "beta_rad", "euler")
    }


def _check_descent(s: dict, start_m: float) -> None:
    g = HapsGains.load()
    t, h, eas = s["t"], s["alt_msl_m"], s["eas_mps"]
    # descending phase: demand beyond the schedule band, after the first minute's transition
    desc = (h > TARGET_M + g.schedule_band_m + 20.0) & (t > 60.0)
    assert desc.sum() > 300
    assert abs(eas[desc].mean() - g.descent_eas) < 0.3
    assert np.abs(eas[desc] - g.descent_eas).max() < 1.0
    # sink rate over 10 s: within the limit (+35 % for the phugoid: worst of 20 seeds 1.251 x,
    # seed 17; without the glide limit it is 0.8 m/s = 2.3 x), and the descent does go on
    sink = -(h[10:] - h[:-10]) / (t[10:] - t[:-10])
    in_desc = desc[10:]
    limit = np.minimum(g.sink_rate_max, _glide_sink(g, s["tas_mps"][10:] / s["eas_mps"][10:]))
    assert (sink[in_desc] <= 1.35 * limit[in_desc]).all()
    assert sink[in_desc].mean() > 0.8 * limit[in_desc].mean()
    # never near the stall: 1.2 x stall once on the schedule's EAS; before that, never slower
    # than the start (the station's EAS 7.5 m/s is 1.11 x stall by design: the whole flight
    # starts there and speeds up); bank within the limit (a lateral divergence banks beyond 40 deg)
    flying = t > 5.0
    on_schedule = int(np.argmax(eas >= g.descent_eas - 0.3))
    assert eas[flying].min() > min(eas[0], 1.2 * STALL_EAS) - 0.05
    assert eas[on_schedule:].min() > 1.2 * STALL_EAS
    assert np.degrees(s["alpha_rad"]).max() < ALPHA_CLMAX_DEG - 3.0
    assert np.degrees(np.abs(s["euler"][:, 0])).max() < g.roll_limit_rad * 180.0 / math.pi + 5.0
    # ends holding the commanded altitude at the cruise speed
    assert h[0] == pytest.approx(start_m, abs=1.0)
    end = t > t[-1] - 200.0
    assert np.abs(h[end] - TARGET_M).max() < 5.0
    assert np.abs(eas[end] - CRUISE_EAS).max() < 0.8


@pytest.mark.closed_loop
def test_last_500_m_of_the_descent_on_the_schedule(scenario_data, fly):
    """1.5 km -> 1 km: glide-limited sink (0.35 m/s) at EAS 9 m/s, then 1 km at EAS 10 m/s."""
    data = scenario_data(SCENARIO)
    data["vehicle"][0]["initial"] |= {"altitude": 1500.0, "airspeed": 10.8}  # EAS 10.2 m/s
    data["duration"] = 1800.0
    _check_descent(_states(fly(data)), 1500.0)


@pytest.mark.slow
@pytest.mark.closed_loop
def test_descent_from_station_to_1_km(fly):
    """The shipped scenario whole: 18 km -> 1 km in ~9.1 h (0.8 m/s above ~16 km, the glide
    sink below)."""
    s = _states(fly(SCENARIO))
    _check_descent(s, 18_000.0)
    reached = s["t"][s["alt_msl_m"] < TARGET_M + 5.0]
    assert reached.size and 8.5 * 3600.0 < reached[0] < 9.6 * 3600.0


@pytest.mark.slow
@pytest.mark.closed_loop
@pytest.mark.parametrize("seed", range(1, 21), ids=lambda s: f"seed{s:02d}")
def test_last_500_m_across_seeds(scenario_data, fly, seed):
    """The CI descent segment on 20 seeds (sensor noise, EKF)."""
    data = scenario_data(SCENARIO)
    data["vehicle"][0]["initial"] |= {"altitude": 1500.0, "airspeed": 10.8}
    data["duration"], data["seed"] = 1800.0, seed
    _check_descent(_states(fly(data)), 1500.0)


def _hold_1_km_at_eas_8(scenario_data, fly, seed: int):
    """The scenario's 3 km square at 1 km from its west side's middle, at TAS 8.5 m/s (EAS
    8.1 m/s, the station's 1.2 x stall), through its first corner."""
    data = scenario_data(SCENARIO)
    vehicle = data["vehicle"][0]
    vehicle["initial"] |= {"north": 0.0, "altitude": TARGET_M, "airspeed": 8.5}
    vehicle["mission"]["cruise_speed"] = 8.5
    vehicle["mission"]["waypoints"] = [w | {"altitude": TARGET_M} for w in vehicle["mission"]["waypoints"]]
    data["duration"], data["seed"] = 260.0, seed
    run = fly(data)
    s = _states(run)
    track = np.array([m["cross_track_m"] for _, m in read_topic(run.path, "/haps/truth/tracking")])
    events = [m.message for _, m in read_topic(run.path, "/log")]
    return s, track, events


def _check_low_speed_hold(s: dict, track: np.ndarray, events: list[str]) -> None:
    g = HapsGains.load()
    bank_max = math.degrees(math.atan(8.5**2 / (STANDARD_GRAVITY * g.turn_radius_min_m)))  # 4.95 deg
    assert any("waypoint 1/4 reached" in e for e in events)  # through the corner
    assert np.degrees(np.abs(s["euler"][:, 0])).max() < bank_max + 1.0
    assert np.degrees(np.abs(s["beta_rad"])).max() < 8.0
    # no dive (the divergence reached EAS 15.6 m/s) and above the stall with a margin; the TECS
    # speed dips on the EKF reach 7.29 m/s (seed 8 of 1-8; seed 7 flew 7.56-8.47 m/s)
    eas = s["eas_mps"][10:]
    assert eas.max() < 8.1 + 0.8 and eas.min() > 1.05 * STALL_EAS
    assert np.abs(s["alt_msl_m"] - TARGET_M).max() < 5.0
    assert np.abs(track[-60:]).max() < 5.0  # back on the next leg


@pytest.mark.closed_loop
def test_holding_1_km_at_eas_8_through_a_turn_stays_coordinated(scenario_data, fly):
    """Before the bank was limited to the 85 m minimum turn radius and L1 kept at least that far
    ahead, this hold diverged in the first turn (bank 48 deg, sideslip 27 deg, EAS 15.6 m/s):
    at TAS 8.5 m/s a 13 deg bank turns at 37 m radius, the 25 m wing's yaw rate r b/(2V) = 0.34
    overbanks it beyond full aileron (aircraft/haps/README.md "Low-speed turns")."""
    _check_low_speed_hold(*_hold_1_km_at_eas_8(scenario_data, fly, 1))


@pytest.mark.slow
@pytest.mark.closed_loop
@pytest.mark.parametrize("seed", range(1, 21), ids=lambda s: f"seed{s:02d}")
def test_holding_1_km_at_eas_8_across_seeds(scenario_data, fly, seed):
    _check_low_speed_hold(*_hold_1_km_at_eas_8(scenario_data, fly, seed))
