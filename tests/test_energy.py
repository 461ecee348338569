"""Energy model: solar power at local noon against a hand computation, attitude and altitude
act, battery limits, and the energy balance of a closed-loop flight read back from the MCAP."""

import math
from datetime import UTC, datetime

import numpy as np
import pytest

from aircraft.registry import get_airframe
from sim.energy.altitude_schedule import AltitudeManager, AltitudeSchedule
from sim.energy.battery import Battery
from sim.energy.params import EnergyConfigError, EnergyParams
from sim.energy.solar import SunTracker, array_power
from sim.mcap_read import read_topic
from sim.runner import run_scenario
from sim.scenario import ScenarioError, load_scenario, parse_scenario
from sim.sensors import isa

PARAMS = EnergyParams.load(get_airframe("haps").energy_file)
LAT, LON = 47.0, 8.0


def _noon_utc(day: datetime) -> datetime:
    """Local solar noon at LON: 12:00 minus longitude/15 h minus the equation of time
    (Spencer 1971, minutes)."""
    n = day.timetuple().tm_yday
    g = 2 * math.pi * (n - 1) / 365
    eot = 229.18 * (
        0.000075
        + 0.001868 * math.cos(g)
        - 0.032077 * math.sin(g)
        - 0.014615 * math.cos(2 * g)
        - 0.040849 * math.sin(2 * g)
    )
    minutes = 12 * 60 - LON * 4 - eot
    return day.replace(hour=int(minutes // 60), minute=int(minutes % 60), second=int(60 * (minutes % 1)))


def _hand_noon_power(day: datetime, alt_m: float) -> float:
    """Textbook chain, independent of pvlib's code: declination (Spencer 1971), zenith at solar
    noon = lat - declination, extraterrestrial irradiance 1367 (1 + 0.033 cos(2 pi n / 365)),
    Kasten-Young air mass; beam transmittance of Bird & Hulstrom (1981) for what lies above a
    HAPS: Rayleigh and mixed gases on the pressure-corrected air mass, ozone (0.3 atm-cm) on the
    plain air mass; water vapour and aerosol neglected (< 0.5 % above 18 km), and so is the sky
    diffuse light the model adds (~1.5 %). Flat array facing up."""
    n = day.timetuple().tm_yday
    g = 2 * math.pi * (n - 1) / 365
    decl = (
        0.006918
        - 0.399912 * math.cos(g)
        + 0.070257 * math.sin(g)
        - 0.006758 * math.cos(2 * g)
        + 0.000907 * math.sin(2 * g)
        - 0.002697 * math.cos(3 * g)
        + 0.00148 * math.sin(3 * g)
    )
    zen = abs(math.radians(LAT) - decl)
    e0 = 1367.0 * (1 + 0.033 * math.cos(2 * math.pi * n / 365))
    am = 1.0 / (math.cos(zen) + 0.50572 * (96.07995 - math.degrees(zen)) ** -1.6364)
    amp = am * isa.pressure_at_altitude(alt_m) / isa.P0
    t_rayleigh = math.exp(-0.0903 * amp**0.84 * (1 + amp - amp**1.01))
    x = 0.3 * am
    t_ozone = 1 - 0.1611 * x * (1 + 139.48 * x) ** -0.3034 - 0.002715 * x / (1 + 0.044 * x + 0.0003 * x * x)
    t_gases = math.exp(-0.0127 * amp**0.26)
    dni = 0.9662 * e0 * t_rayleigh * t_ozone * t_gases  # 0.9662: Bird's spectral-band factor
    a = PARAMS.array
    return dni * math.cos(zen) * a.area_m2 * a.cell_efficiency * a.mppt_efficiency


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


@pytest.mark.closed_loop
def test_energy_balance_of_a_flight_within_one_percent(tmp_path):
    """Box mission (shipped), 10 min: integrated logged powers (trapezoid) equal the change of
    stored energy plus losses and curtailed power within 1 % of the energy moved."""
    scenario, text = load_scenario("scenarios/haps_box_mission.toml")
    path = tmp_path / "box.mcap"
    run_scenario(scenario, path, scenario_text=text, duration=600.0)
    rec = [m for _, m in read_topic(path, "/haps/energy")]
    assert len(rec) > 5000
    t = np.array([r["t"] for r in rec])
    col = {k: np.array([r[k] for r in rec]) for k in ("solar_w", "propulsion_w", "loads_w", "loss_w", "curtailed_w")}
    net = col["solar_w"] - col["propulsion_w"] - col["loads_w"] - col["loss_w"] - col["curtailed_w"]
    integrated_wh = float(np.sum(0.5 * (net[1:] + net[:-1]) * np.diff(t))) / 3600.0
    stored_wh = rec[-1]["energy_wh"] - rec[0]["energy_wh"]
    moved_wh = float(np.sum(np.abs(col["solar_w"][1:]) + col["propulsion_w"][1:]) * np.diff(t).mean()) / 3600.0
    assert abs(integrated_wh - stored_wh) < 0.01 * moved_wh, (integrated_wh, stored_wh, moved_wh)
    # propulsion power is JSBSim's: on average the trim's shaft power over the motor efficiency
    assert col["propulsion_w"].mean() == pytest.approx(746.0 / PARAMS.loads.motor_efficiency, rel=0.15)
    assert 0.0 < rec[-1]["state_of_charge"] <= 1.0 and not rec[-1]["depleted"]


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
