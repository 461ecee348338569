"""Energy model: solar power at local noon against a hand computation, attitude and altitude
act, battery limits, and the energy balance of a closed-loop flight read back from the MCAP."""

import math
from datetime import UTC, datetime, timedelta

import numpy as np
import pytest

from aircraft.registry import get_airframe
from sim.energy.altitude_schedule import AltitudeManager, AltitudeSchedule
from sim.energy.battery import Battery
from sim.energy.params import EnergyConfigError, EnergyParams
from sim.energy.solar import SunTracker, array_power
from sim.mcap_read import read_topic
from sim.runner import run_scenario
from sim.scenario import ScenarioError, parse_scenario
from sim.sensors import isa

PARAMS = EnergyParams.load(get_airframe("haps").energy_file)
LAT, LON = 47.0, 8.0


def _declination_eot(day: datetime) -> tuple[float, float]:
    """Solar declination [rad] and equation of time [min] of the day (Spencer 1971)."""
    g = 2 * math.pi * (day.timetuple().tm_yday - 1) / 365
    decl = (
        0.006918
        - 0.399912 * math.cos(g)
        + 0.070257 * math.sin(g)
        - 0.006758 * math.cos(2 * g)
        + 0.000907 * math.sin(2 * g)
        - 0.002697 * math.cos(3 * g)
        + 0.00148 * math.sin(3 * g)
    )
    eot = 229.18 * (
        0.000075
        + 0.001868 * math.cos(g)
        - 0.032077 * math.sin(g)
        - 0.014615 * math.cos(2 * g)
        - 0.040849 * math.sin(2 * g)
    )
    return decl, eot


def _noon_utc(day: datetime) -> datetime:
    """Local solar noon at LON: 12:00 minus longitude/15 h minus the equation of time."""
    minutes = 12 * 60 - LON * 4 - _declination_eot(day)[1]
    return day.replace(hour=int(minutes // 60), minute=int(minutes % 60), second=int(60 * (minutes % 1)))


def _hand_dni(day: datetime, zen: float, alt_m: float) -> float:
    """Textbook beam irradiance [W/m^2] at zenith angle ``zen`` [rad], independent of pvlib's
    code: extraterrestrial irradiance 1367 (1 + 0.033 cos(2 pi n / 365)), Kasten-Young air mass;
    beam transmittance of Bird & Hulstrom (1981) for what lies above a HAPS: Rayleigh and mixed
    gases on the pressure-corrected air mass, ozone (0.3 atm-cm) on the plain air mass; water
    vapour and aerosol neglected (< 0.5 % above 18 km), and so is the sky diffuse light the
    model adds (~1.5 %)."""
    n = day.timetuple().tm_yday
    e0 = 1367.0 * (1 + 0.033 * math.cos(2 * math.pi * n / 365))
    am = 1.0 / (math.cos(zen) + 0.50572 * (96.07995 - math.degrees(zen)) ** -1.6364)
    amp = am * isa.pressure_at_altitude(alt_m) / isa.P0
    t_rayleigh = math.exp(-0.0903 * amp**0.84 * (1 + amp - amp**1.01))
    x = 0.3 * am
    t_ozone = 1 - 0.1611 * x * (1 + 139.48 * x) ** -0.3034 - 0.002715 * x / (1 + 0.044 * x + 0.0003 * x * x)
    t_gases = math.exp(-0.0127 * amp**0.26)
    return 0.9662 * e0 * t_rayleigh * t_ozone * t_gases  # 0.9662: Bird's spectral-band factor


def _hand_noon_power(day: datetime, alt_m: float) -> float:
    """Array power [W] at local solar noon, flat array facing up: zenith = lat - declination."""
    zen = abs(math.radians(LAT) - _declination_eot(day)[0])
    a = PARAMS.array
    return _hand_dni(day, zen, alt_m) * math.cos(zen) * a.area_m2 * a.cell_efficiency * a.mppt_efficiency


def _hand_array_power(when: datetime, lat: float, lon: float, alt_m: float, euler: np.ndarray) -> float:
    """Array power [W] for a wing at ``euler`` (roll, pitch, yaw [rad]) at ``when`` (UTC):
    hour angle from the equation of time, the sun's vector in NED by spherical trigonometry,
    the upper-surface normal (body -z) in NED written out for the 3-2-1 rotation."""
    decl, eot = _declination_eot(when)
    minutes = when.hour * 60 + when.minute + when.second / 60 + when.microsecond / 6e7
    h = math.radians((minutes + 4 * lon + eot - 720.0) / 4.0)
    phi = math.radians(lat)
    sun = np.array(
        [
            math.sin(decl) * math.cos(phi) - math.cos(decl) * math.sin(phi) * math.cos(h),
            -math.cos(decl) * math.sin(h),
            -(math.sin(phi) * math.sin(decl) + math.cos(phi) * math.cos(decl) * math.cos(h)),
        ]
    )
    r, p, y = (float(v) for v in euler)
    normal = -np.array(
        [
            math.cos(y) * math.sin(p) * math.cos(r) + math.sin(y) * math.sin(r),
            math.sin(y) * math.sin(p) * math.cos(r) - math.cos(y) * math.sin(r),
            math.cos(p) * math.cos(r),
        ]
    )
    a = PARAMS.array
    zen = math.acos(-sun[2])
    cos_inc = max(0.0, float(normal @ sun))
    return _hand_dni(when, zen, alt_m) * cos_inc * a.area_m2 * a.cell_efficiency * a.mppt_efficiency


@pytest.mark.parametrize("day", [datetime(2026, 6, 21, tzinfo=UTC), datetime(2026, 3, 20, tzinfo=UTC)])
def test_solar_power_at_local_noon_matches_hand_computation(day):
    noon = _noon_utc(day)
    sun = SunTracker(noon, PARAMS.atmosphere).sample(0.0, LAT, LON, 18_000.0)
    power, cos_inc = array_power(PARAMS.array, sun, np.zeros(3))
    hand = _hand_noon_power(day, 18_000.0)
    assert power == pytest.approx(hand, rel=0.03)
    assert cos_inc == pytest.approx(math.cos(math.radians(90.0 - sun.elevation_deg)), abs=1e-9)


def test_attitude_and_altitude_act_on_solar_power():
    noon = _noon_utc(datetime(2026, 12, 21, tzinfo=UTC))  # sun low in the south (elevation ~20 deg)
    tracker = SunTracker(noon, PARAMS.atmosphere)
    sun = tracker.sample(0.0, LAT, LON, 18_000.0)
    level, _ = array_power(PARAMS.array, sun, np.zeros(3))
    heading_east = math.radians(90.0)
    toward, _ = array_power(PARAMS.array, sun, np.array([math.radians(20.0), 0.0, heading_east]))  # right wing down
    away, _ = array_power(PARAMS.array, sun, np.array([math.radians(-20.0), 0.0, heading_east]))
    assert toward > 1.5 * level > 2.0 * away > 0.0
    low = SunTracker(noon, PARAMS.atmosphere).sample(0.0, LAT, LON, 0.0)
    assert array_power(PARAMS.array, low, np.zeros(3))[0] < 0.9 * level  # more air, more loss
    night = SunTracker(noon, PARAMS.atmosphere).sample(0.0, LAT, LON + 180.0, 18_000.0)
    assert night.elevation_deg < 0.0 and array_power(PARAMS.array, night, np.zeros(3))[0] == 0.0


def test_battery_efficiencies_and_limits():
    b = Battery(PARAMS.battery, soc=0.5)
    e0 = b.energy_wh
    s = b.step(1000.0, 3600.0)
    assert b.energy_wh - e0 == pytest.approx(1000.0 * PARAMS.battery.charge_efficiency)
    assert s.loss_w == pytest.approx(1000.0 * (1 - PARAMS.battery.charge_efficiency))
    s = b.step(-500.0, 3600.0)
    assert s.stored_w == pytest.approx(-500.0 / PARAMS.battery.discharge_efficiency)
    big = b.step(1e5, 1.0)
    assert big.stored_w == pytest.approx(PARAMS.battery.max_charge_w * PARAMS.battery.charge_efficiency)
    full = Battery(PARAMS.battery, soc=1.0)
    s = full.step(800.0, 10.0)
    assert s.curtailed_w == 800.0 and full.soc == 1.0
    empty = Battery(PARAMS.battery, soc=0.0)
    s = empty.step(-300.0, 10.0)
    assert s.shortfall_w == 300.0 and empty.soc == 0.0


def test_bad_energy_file_is_rejected(tmp_path):
    text = get_airframe("haps").energy_file.read_text().replace("area_m2 = 15.0", "area_m2 = -1.0")
    p = tmp_path / "energy.toml"
    p.write_text(text)
    with pytest.raises(EnergyConfigError, match=r"array\.area_m2"):
        EnergyParams.load(p)


NOON = _noon_utc(datetime(2026, 6, 21, tzinfo=UTC))
STARTS = {"noon": NOON - timedelta(minutes=2), "night": datetime(2026, 6, 21, 23, 0, tzinfo=UTC)}


@pytest.fixture(scope="module")
def station_flight(fly_in, scenario_data, tmp_path_factory):
    """Four minutes of the shipped June station scenario (EKF, 18 km, EAS 7.5 m/s, battery half
    full) from ``STARTS[case]``, 1 km before the square's north-west corner (a banked turn at
    ~40 s), logged at the control rate: one /haps/energy record per power-system step. Each
    case is flown once per module."""
    flights = {}

    def flight(case: str):
        if case not in flights:
            data = scenario_data("haps_station_june_47n")
            data["start_time"], data["duration"] = STARTS[case].strftime("%Y-%m-%dT%H:%M:%SZ"), 240.0
            data["logging"]["rate_hz"] = 10.0
            data["vehicle"][0]["initial"]["north"] = "4 km"
            flights[case] = fly_in(tmp_path_factory.mktemp(case), data, case).log
        return flights[case]

    return flight


@pytest.mark.closed_loop
@pytest.mark.parametrize("case", ["noon", "night"])
def test_energy_balance_of_a_closed_loop_flight_within_one_percent(station_flight, case):
    """Four minutes of the shipped station flight, charging at local noon and discharging at
    night, read back from the MCAP: the logged bus powers integrated over the steps equal the
    change of state of charge x the usable capacity (from energy.toml) plus the conversion
    losses and the curtailed power within 1 % of that change; the losses are the files'
    efficiencies of the power through the battery, the charge limit caps what is taken, and the
    propulsion power is JSBSim's motors: the commanded throttles x their rated 1.5 kW over the
    motor efficiency, one control step earlier."""
    log = station_flight(case)
    rec = log.topic("/haps/energy").messages
    col = {k: np.array([r[k] for r in rec]) for k in rec[0] if k != "cumulative_wh"}
    dt = np.diff(col["t"])
    assert np.allclose(dt, 0.1)  # every step logged
    step = slice(1, None)  # record i: the step ending at t_i
    bus = (col["solar_w"] - col["propulsion_w"] - col["loads_w"])[step]
    capacity_wh = PARAMS.battery.mass_kg * PARAMS.battery.cell_specific_energy_wh_kg * PARAMS.battery.packaging_factor
    delta_wh = (col["state_of_charge"][-1] - col["state_of_charge"][0]) * capacity_wh
    losses_wh = float(np.sum((col["loss_w"] + col["curtailed_w"] - col["shortfall_w"])[step] * dt)) / 3600.0
    integrated_wh = float(np.sum(bus * dt)) / 3600.0
    assert abs(delta_wh) > 20.0 and np.sign(delta_wh) == (1 if case == "noon" else -1)
    assert abs(integrated_wh - (delta_wh + losses_wh)) < 0.01 * abs(delta_wh), (integrated_wh, delta_wh, losses_wh)
    b = PARAMS.battery
    charging = bus > 0.0
    taken = np.where(charging, np.minimum(bus, b.max_charge_w), 0.0)
    assert np.allclose(col["loss_w"][step][charging], (1 - b.charge_efficiency) * taken[charging], rtol=1e-9)
    assert np.allclose(col["curtailed_w"][step], np.where(charging, bus - taken, 0.0), atol=1e-6)
    drawn = -bus[~charging] / b.discharge_efficiency
    assert np.allclose(col["loss_w"][step][~charging], (1 - b.discharge_efficiency) * drawn, rtol=1e-9)
    if case == "noon":
        assert col["curtailed_w"].max() > 0.0  # the charge limit acts at noon
    else:
        assert not charging.any() and col["solar_w"].max() == 0.0
    cmd = log.topic("/haps/ctrl/commands").messages
    throttle = np.array([sum(v for k, v in m["properties"].items() if k.startswith("fcs/throttle-cmd")) for m in cmd])
    shaft_w = throttle[:-1] * 1500.0
    np.testing.assert_allclose(col["propulsion_w"][1:], shaft_w / PARAMS.loads.motor_efficiency, rtol=1e-6)


@pytest.mark.closed_loop
def test_closed_loop_solar_power_at_local_noon_matches_hand_computation(station_flight):
    """The same noon flight's logged array power against the hand computation (Spencer
    declination and equation of time, spherical trigonometry for the sun, the wing's logged
    attitude for the array normal, Bird & Hulstrom beam transmittance) at each logged step:
    within 3 %, level and in the square's banked turns alike."""
    log = station_flight("noon")
    rec, msgs = log.topic("/haps/energy").messages, log.topic("/haps/truth/state").messages
    assert len(msgs) == len(rec)
    hand = np.array(
        [
            _hand_array_power(
                STARTS["noon"] + timedelta(seconds=m["t"]), m["lat_deg"], m["lon_deg"], m["alt_msl_m"], m["euler"]
            )
            for m in msgs
        ]
    )
    solar = np.array([r["solar_w"] for r in rec])
    np.testing.assert_allclose(solar, hand, rtol=0.03)
    bank = np.degrees(np.abs([m["euler"][0] for m in msgs]))
    assert bank.max() > 10.0  # a turn of the square is in the window


def test_altitude_schedule_climbs_on_a_full_battery_and_glides_down_below_the_low_mark():
    s = AltitudeSchedule(floor_m=18_000.0, ceiling_m=21_000.0, soc_high=0.95, soc_low=0.90)
    m = AltitudeManager(s, soc=0.5)
    assert m.altitude(0.5) == 18_000.0
    assert m.altitude(0.94) == 18_000.0  # charging: not yet
    assert m.altitude(0.95) == 21_000.0  # full: store the surplus as height
    assert m.altitude(0.92) == 21_000.0  # hysteresis: keeps climbing/holding
    assert m.altitude(0.90) == 18_000.0  # the sun no longer covers it: glide down to the floor
    assert m.altitude(0.93) == 18_000.0
    assert AltitudeManager(s, soc=1.0).altitude(0.97) == 21_000.0
    with pytest.raises(ValueError, match="floor"):
        AltitudeSchedule(floor_m=21_000.0, ceiling_m=18_000.0)


def _vehicle_with(**energy) -> dict:
    return {
        "name": "x",
        "seed": 1,
        "duration": 10.0,
        "origin": {"lat": 47.0, "lon": 8.0},
        "vehicle": [
            {
                "name": "haps",
                "aircraft": "haps",
                "initial": {"altitude": 18_000.0, "airspeed": 26.0},
                "mission": {"cruise_speed": 26.0, "waypoints": [{"north": 1e4, "east": 0.0, "altitude": 18_000.0}]},
                "energy": energy,
            }
        ],
    }


def test_scenario_energy_options_are_checked():
    ok = parse_scenario(_vehicle_with(initial_soc=0.3, altitude_schedule={"floor": 18_000.0, "ceiling": 21_000.0}))
    assert ok.vehicle[0].energy.altitude_schedule.ceiling == 21_000.0
    for bad, msg in (
        ({"initial_soc": 1.5}, "initial_soc"),
        ({"altitude_schedule": {"floor": 21_000.0, "ceiling": 18_000.0}}, "floor must be below ceiling"),
        ({"enabled": False, "initial_soc": 0.5}, "without a power-system model"),
    ):
        with pytest.raises(ScenarioError, match=msg):
            parse_scenario(_vehicle_with(**bad))


def test_initial_state_of_charge_acts(tmp_path):
    soc = {}
    for s0 in (0.3, 0.8):
        path = tmp_path / f"{s0}.mcap"
        run_scenario(parse_scenario(_vehicle_with(initial_soc=s0)), path)
        soc[s0] = read_topic(path, "/haps/energy")[0][1]["state_of_charge"]
    assert soc[0.3] == pytest.approx(0.3, abs=1e-3) and soc[0.8] == pytest.approx(0.8, abs=1e-3)


def test_empty_battery_is_an_event_and_stops_the_motors(tmp_path):
    """Night (21 December 18:00 UTC at 47 N), battery almost empty: energy_depleted within
    seconds, the motors' shaft power drops to zero and stays there."""
    data = _vehicle_with(initial_soc=0.0005)
    data["start_time"] = "2026-12-21T18:00:00Z"
    data["duration"] = 60.0
    path = tmp_path / "empty.mcap"
    run_scenario(parse_scenario(data), path)
    events = [(t, m.message) for t, m in read_topic(path, "/log")]
    depleted = [t for t, msg in events if "energy_depleted" in msg]
    assert len(depleted) == 1 and depleted[0] < 30.0
    rec = [m for _, m in read_topic(path, "/haps/energy")]
    after = [r for r in rec if r["t"] > depleted[0] + 1.0]
    assert after and all(r["propulsion_w"] == 0.0 and r["depleted"] for r in after)
    assert all(r["solar_w"] == 0.0 for r in rec)
