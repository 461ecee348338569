"""HAPS autopilot: gains file, L1 guidance geometry, TECS logic, and closed loops on the JSBSim
model (truth as the estimate; JSBSim at 120 Hz, outer loops and L1 at 10 Hz)."""

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from aircraft import airframe_dir
from aircraft.haps.autopilot import HapsAutopilot
from aircraft.haps.gains import DEFAULT_PATH, GainsError, HapsGains
from guidance.l1 import L1Guidance
from sim.core.setpoints import FixedWingSetpoint
from sim.core.state import VehicleState
from sim.geodesy import GeoPoint
from sim.jsbsim_plant import InitialConditions, JSBSimPlant

ORIGIN = GeoPoint(47.0, 8.0, 0.0)
ALT, TAS = 20_000.0, 29.7  # trim at EAS 8 m/s
STEPS_PER_CONTROL = 12  # 120 Hz plant / 10 Hz control
DT = 0.1
OVERSHOOT = math.radians(1.0)  # bank beyond the command limit allowed by the inner loop dynamics


# -- gains file ----------------------------------------------------------------------------------


def test_default_gains_load_in_code_units():
    g = HapsGains.load()
    assert g.roll_limit_rad == pytest.approx(math.radians(20.0))
    assert g.roll_limit_rad <= math.radians(25.0)
    assert g.pitch_min_rad < 0.0 < g.pitch_max_rad <= math.radians(15.0)
    assert g.fcs_properties()["ap/qbar-ref-psf"] == pytest.approx(0.8187, rel=1e-3)


def _edited(tmp_path: Path, old: str, new: str) -> Path:
    text = DEFAULT_PATH.read_text()
    assert old in text
    p = tmp_path / "gains.toml"
    p.write_text(text.replace(old, new, 1))
    return p


@pytest.mark.parametrize(
    "old,new,match",
    [
        ("[tecs]\n", "[tecs]\nthr_dampp = 0.1\n", r"\[tecs\]: unknown key\(s\) thr_dampp; allowed here: .*thr_damp"),
        ("[l1]\n", "[l1x]\n", r"unknown section\(s\) l1x"),
        ("kp_roll = 12.0", "", r"\[inner\]: missing key\(s\) kp_roll"),
        ("kp_roll = 12.0", 'kp_roll = "12"', r"kp_roll must be a number"),
    ],
)
def test_gains_file_is_strict(tmp_path, old, new, match):
    with pytest.raises(GainsError, match=match):
        HapsGains.load(_edited(tmp_path, old, new))


# -- L1 geometry (point-mass kinematics, no JSBSim) -----------------------------------------------


def _state(n, e, course, speed=30.0) -> VehicleState:
    return VehicleState(
        t=0.0,
        pos_ned=np.array([n, e, -ALT]),
        vel_ned=np.array([speed * math.cos(course), speed * math.sin(course), 0.0]),
        euler=np.array([0.0, 0.0, course]),
        rates_body=np.zeros(3),
        alt_msl_m=ALT,
        lat_deg=0.0,
        lon_deg=0.0,
        tas_mps=speed,
        eas_mps=8.0,
    )


def _fly_point_mass(l1, n, e, course, a, b, seconds, speed=30.0):
    """Coordinated turns at the commanded bank: course rate g tan(roll) / V."""
    track = []
    for _ in range(int(seconds / DT)):
        roll, xt = l1.update(_state(n, e, course, speed), a, b)
        assert abs(roll) <= l1.roll_limit_rad + 1e-12
        course += 9.80665 * math.tan(roll) / speed * DT
        n += speed * math.cos(course) * DT
        e += speed * math.sin(course) * DT
        track.append((n, e, course, xt))
    return np.array(track)


def test_l1_signs():
    l1 = L1Guidance(25.0, 0.75, math.radians(20.0))
    a, b = np.zeros(3), np.array([10_000.0, 0.0, 0.0])  # northbound track
    roll, xt = l1.update(_state(1000.0, 50.0, 0.0), a, b)  # right of track, flying north
    assert xt == pytest.approx(50.0) and roll < 0.0
    roll, xt = l1.update(_state(1000.0, -50.0, 0.0), a, b)
    assert xt == pytest.approx(-50.0) and roll > 0.0
    roll, xt = l1.update(_state(1000.0, 0.0, 0.0), a, b)
    assert xt == pytest.approx(0.0) and roll == pytest.approx(0.0)


def test_l1_captures_from_far_off_at_most_45_deg():
    l1 = L1Guidance(25.0, 0.75, math.radians(20.0))
    a, b = np.zeros(3), np.array([100_000.0, 0.0, 0.0])
    tr = _fly_point_mass(l1, 0.0, 5000.0, math.radians(180.0), a, b, 600.0)  # 5 km right, flying away
    mid = (np.abs(tr[:, 3]) < 4000.0) & (np.abs(tr[:, 3]) > 1000.0)
    intercept = np.abs(np.remainder(tr[mid, 2] + math.pi, 2 * math.pi) - math.pi)  # |course| from north
    assert mid.any() and intercept.max() <= math.radians(46.0)
    assert np.abs(tr[-600:, 3]).max() < 1.0


def test_l1_behind_a_flies_to_a_and_past_b_returns():
    l1 = L1Guidance(25.0, 0.75, math.radians(20.0))
    a, b = np.zeros(3), np.array([20_000.0, 0.0, 0.0])
    tr = _fly_point_mass(l1, -5000.0, 2000.0, math.radians(90.0), a, b, 400.0)  # behind A, off to the side
    closest_to_a = np.hypot(tr[:, 0], tr[:, 1]).min()
    assert closest_to_a < 500.0
    tr = _fly_point_mass(l1, 25_000.0, 0.0, 0.0, a, b, 400.0)  # 5 km past B, flying on
    assert tr[-1, 0] < 25_000.0 and np.hypot(tr[:, 0] - 20_000.0, tr[:, 1]).min() < 500.0


# -- TECS logic (synthetic states) -----------------------------------------------------------------


def test_first_update_engages_inner_loops_once():
    ap = HapsAutopilot(HapsGains.load())
    s = _state(0.0, 0.0, 0.0)
    ap.reset(s)
    first = ap.update(s, FixedWingSetpoint(0.0, ALT, TAS), DT)
    second = ap.update(s, FixedWingSetpoint(0.0, ALT, TAS), DT)
    assert first["ap/engage"] == 1.0 and first["ap/kp-roll"] == ap.gains.kp_roll
    assert set(second) == {
        "ap/roll-cmd-rad",
        "ap/pitch-cmd-rad",
        "fcs/throttle-cmd-norm[0]",
        "fcs/throttle-cmd-norm[1]",
    }


def test_update_without_reset_starts_from_the_state():
    ap = HapsAutopilot(HapsGains.load())
    s = _state(0.0, 0.0, 0.0, speed=TAS)  # on the setpoint: no rate demands
    s.euler[1] = math.radians(4.3)
    out = ap.update(s, FixedWingSetpoint(0.0, ALT, TAS), DT)
    assert out["ap/engage"] == 1.0
    assert out["ap/pitch-cmd-rad"] == pytest.approx(math.radians(4.3), abs=math.radians(0.2))
    assert 0.2 < out["fcs/throttle-cmd-norm[0]"] < 0.4  # level-flight feed-forward at 20 km


def test_underspeed_pitches_down_for_speed():
    g = HapsGains.load()
    pitch = {}
    for eas in (g.eas_underspeed + 0.2, g.eas_underspeed - 0.2):
        ap = HapsAutopilot(g)
        s = _state(0.0, 0.0, 0.0, speed=TAS * eas / 8.0)
        s.eas_mps = eas
        ap.reset(s)
        out = ap.update(s, FixedWingSetpoint(0.0, ALT + 200.0, TAS), DT)  # climb and speed up
        pitch[eas < g.eas_underspeed] = (out["ap/pitch-cmd-rad"], ap.debug["underspeed"])
    assert pitch[False][1] == 0.0 and pitch[True][1] == 1.0
    assert pitch[True][0] < pitch[False][0]


def test_roll_command_is_limited_and_slewed():
    g = HapsGains.load()
    ap = HapsAutopilot(g)
    s = _state(0.0, 0.0, 0.0)
    ap.reset(s)
    rolls = [ap.update(s, FixedWingSetpoint(1.0, ALT, TAS), DT)["ap/roll-cmd-rad"] for _ in range(100)]
    assert np.diff(rolls).max() <= g.roll_rate_limit_rad_s * DT + 1e-12
    assert rolls[-1] == pytest.approx(g.roll_limit_rad)


def test_bank_is_limited_to_the_minimum_turn_radius_at_low_airspeed():
    """At TAS 8.5 m/s (EAS 8.1 m/s at 1 km) the bank command stops at atan(V^2 / (g R_min)),
    ~5 deg; halving R_min raises it; at 30 m/s the 20 deg limit binds."""
    g = HapsGains.load()
    for gains, speed in ((g, 8.5), (dataclasses.replace(g, turn_radius_min_m=g.turn_radius_min_m / 2), 8.5), (g, 30.0)):
        ap = HapsAutopilot(gains)
        s = _state(0.0, 0.0, 0.0, speed)
        ap.reset(s)
        roll = [ap.update(s, FixedWingSetpoint(1.0, ALT, speed), DT)["ap/roll-cmd-rad"] for _ in range(100)][-1]
        expected = min(g.roll_limit_rad, math.atan(speed * speed / (9.80665 * gains.turn_radius_min_m)))
        assert roll == pytest.approx(expected, rel=1e-9) and ap.debug["bank_max_rad"] == pytest.approx(expected)
    assert math.degrees(math.atan(8.5**2 / (9.80665 * g.turn_radius_min_m))) == pytest.approx(4.95, abs=0.05)


def test_l1_distance_floor_softens_the_demand_at_low_speed():
    """At 8.5 m/s the L1 distance 0.75 x 25 x V / pi = 51 m is below the 85 m floor: the same
    cross-track error asks for a lateral acceleration smaller by 51/85 (small angles)."""
    a, b = np.zeros(3), np.array([10_000.0, 0.0, 0.0])
    s = _state(1000.0, 2.0, 0.0, 8.5)
    free = L1Guidance(25.0, 0.75, math.radians(20.0)).update(s, a, b).roll_rad
    floored = L1Guidance(25.0, 0.75, math.radians(20.0), distance_min_m=85.0).update(s, a, b).roll_rad
    l1 = 0.75 * 25.0 * 8.5 / math.pi
    assert math.tan(floored) / math.tan(free) == pytest.approx((l1 / 85.0) ** 2, rel=1e-3)
    assert L1Guidance.for_airframe(HapsAutopilot(HapsGains.load())).distance_min_m == 85.0
    with pytest.raises(ValueError, match="minimum distance"):
        L1Guidance(25.0, 0.75, 0.3, distance_min_m=0.0)


# -- closed loop on the JSBSim model ---------------------------------------------------------------


class Loop:
    """Trimmed HAPS plant + autopilot + L1 at 10 Hz; records what the checks need."""

    def __init__(self, gains: HapsGains | None = None):
        self.plant = JSBSimPlant("haps", 1.0 / 120.0, ORIGIN, airframe_dir("haps"))
        self.plant.initialise(InitialConditions(GeoPoint(ORIGIN.lat_deg, ORIGIN.lon_deg, ALT), tas_mps=TAS))
        self.plant.trim()
        self.ap = HapsAutopilot(gains or HapsGains.load())
        self.l1 = L1Guidance.for_airframe(self.ap)
        s = self.plant.truth()
        self.ap.reset(s, throttle=self.plant["fcs/throttle-cmd-norm[0]"])
        self.start = s.pos_ned.copy()

    def fly(self, seconds: float, a, b, alt_cmd: float, tas_cmd: float) -> dict[str, np.ndarray]:
        rec = []
        for _ in range(round(seconds / DT)):
            s = self.plant.truth()
            roll_cmd, xt = self.l1.update(s, a, b)
            cmds = self.ap.update(s, FixedWingSetpoint(roll_cmd, alt_cmd, tas_cmd), DT)
            self.plant.set_many(cmds)
            self.plant.step(STEPS_PER_CONTROL)
            rec.append(
                (s.t, s.alt_msl_m, s.tas_mps, s.roll, xt, cmds["fcs/throttle-cmd-norm[0]"], *self.ap.debug.values())
            )
        arr = np.array(rec)
        assert np.isfinite(arr).all()  # state, commands and the autopilot's internals
        return {
            "t": arr[:, 0],
            "alt": arr[:, 1],
            "tas": arr[:, 2],
            "roll": arr[:, 3],
            "xt": arr[:, 4],
            "thr": arr[:, 5],
        }


@pytest.mark.closed_loop
def test_closed_loop_90_deg_turn_onto_new_segment():
    loop = Loop()
    north = loop.start + np.array([100_000.0, 0.0, 0.0])
    straight = loop.fly(20.0, loop.start, north, ALT, TAS)
    assert np.abs(straight["xt"]).max() < 1.0
    here = loop.plant.truth().pos_ned.copy()
    east = here + np.array([0.0, 100_000.0, 0.0])
    r = loop.fly(150.0, here, east, ALT, TAS)
    limit = loop.ap.gains.roll_limit_rad
    assert r["roll"].max() > limit - math.radians(1.0)  # the turn used the bank limit
    assert np.abs(r["roll"]).max() <= limit + OVERSHOOT
    settled = r["t"] >= r["t"][0] + 60.0
    assert np.abs(r["xt"][settled]).max() < 20.0
    assert np.abs(r["xt"][-100:]).max() < 2.0
    assert np.abs(r["alt"] - ALT).max() < 10.0  # the turn barely disturbs altitude
    assert np.abs(r["tas"] - TAS).max() < 1.0
    heading = math.degrees(loop.plant.truth().course_rad)
    assert heading == pytest.approx(90.0, abs=1.0)


@pytest.mark.closed_loop
def test_closed_loop_altitude_then_airspeed_step():
    loop = Loop()
    a, b = loop.start, loop.start + np.array([100_000.0, 0.0, 0.0])
    loop.fly(10.0, a, b, ALT, TAS)
    g = loop.ap.gains

    climb = loop.fly(200.0, a, b, ALT + 100.0, TAS)
    assert climb["alt"].max() < ALT + 100.0 + 50.0
    assert np.abs(climb["tas"] - TAS).max() < 2.0
    rate = np.diff(climb["alt"]) / DT
    assert rate.max() < g.climb_rate_max + 0.3  # climb-rate limit (plus transients)
    assert np.abs(climb["alt"][-300:] - (ALT + 100.0)).max() < 5.0
    assert np.abs(climb["tas"][-300:] - TAS).max() < 0.5

    faster = loop.fly(120.0, a, b, ALT + 100.0, TAS + 2.0)
    assert np.abs(faster["alt"] - (ALT + 100.0)).max() < 50.0
    assert faster["tas"].max() < TAS + 2.0 + 2.0
    assert np.abs(faster["tas"][-300:] - (TAS + 2.0)).max() < 0.5
    assert np.abs(faster["alt"][-300:] - (ALT + 100.0)).max() < 5.0

    for rec in (climb, faster):
        assert np.abs(rec["roll"]).max() <= g.roll_limit_rad + OVERSHOOT
        assert ((rec["thr"] >= g.throttle_min) & (rec["thr"] <= g.throttle_max)).all()


@pytest.mark.closed_loop
def test_closed_loop_without_trim_throttle_and_lower_gains_scheduled():
    """Reset without the trim throttle (as the runner does) and fly at EAS 10 m/s, where the
    inner-loop gains are scheduled down: still holds altitude and speed."""
    loop = Loop()
    loop.ap.reset(loop.plant.truth())
    a, b = loop.start, loop.start + np.array([100_000.0, 0.0, 0.0])
    r = loop.fly(150.0, a, b, ALT, TAS * 10.0 / 8.0)
    assert np.abs(r["alt"] - ALT).max() < 50.0
    assert np.abs(r["tas"][-200:] - TAS * 10.0 / 8.0).max() < 0.5
    assert loop.plant["ap/gain-sched"] == pytest.approx(0.64, abs=0.03)


def test_climb_and_descent_follow_the_eas_schedule():
    """Beyond the band the airspeed demand is the schedule's EAS (as TAS at this density ratio),
    whatever the setpoint's airspeed; within it, the setpoint's."""
    g = HapsGains.load()
    ratio = TAS / 8.0  # TAS per EAS of _state
    cases = {
        "climb": (ALT + g.schedule_band_m + 50.0, g.climb_eas * ratio),
        "descent": (ALT - g.schedule_band_m - 50.0, g.descent_eas * ratio),
        "near": (ALT + g.schedule_band_m - 50.0, TAS + 2.0),
    }
    for name, (alt_dem, v_expected) in cases.items():
        ap = HapsAutopilot(g)
        s = _state(0.0, 0.0, 0.0, speed=TAS)
        ap.reset(s)
        ap.update(s, FixedWingSetpoint(0.0, alt_dem, TAS + 2.0), DT)
        assert ap.debug["v_dem_mps"] == pytest.approx(v_expected, rel=1e-9), name


def test_a_planned_airspeed_is_flown_within_the_eas_envelope():
    """A plan's commanded airspeed (e.g. the MPTP's V_cor) is the TECS demand inside the EAS
    envelope and clipped to it outside: at EAS/TAS = 8/29.7, 30 m/s TAS passes; 100 m/s
    becomes eas_max = 12 m/s EAS = 44.55 m/s TAS; 10 m/s becomes eas_min = 7.3 m/s EAS = 27.10 m/s."""
    g = HapsGains.load()
    ratio = TAS / 8.0  # TAS per EAS of _state
    for demand, expected in ((30.0, 30.0), (100.0, g.eas_max * ratio), (10.0, g.eas_min * ratio)):
        ap = HapsAutopilot(g)
        s = _state(0.0, 0.0, 0.0, speed=TAS)
        ap.reset(s)
        ap.update(s, FixedWingSetpoint(0.0, ALT, demand), DT)
        assert ap.debug["v_dem_mps"] == pytest.approx(expected, rel=1e-9), demand
    assert g.eas_max * ratio == pytest.approx(44.55) and g.eas_min * ratio == pytest.approx(27.1012, abs=1e-4)
