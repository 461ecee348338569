"""The wind blows: its physics read from the MCAP (crab angle and wind triangle of the HAPS, lean
of the hovering quadrotor, a HAPS climbing through a profile) and the wind field's interpolation."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from sim.replay.runlog import RunLog
from sim.runner import run_scenario
from sim.scenario import ScenarioError, Wind, parse_scenario
from sim.wind_field import STANDARD_PROFILES, WindField

ROOT = Path(__file__).resolve().parents[1]


def _run(tmp_path: Path, data: dict, name: str = "run") -> RunLog:
    path = tmp_path / f"{name}.mcap"
    run_scenario(parse_scenario(data, name), path, scenario_text=tomli_w.dumps(data))
    return RunLog(path)


def _haps_leg(altitude: float, tas: float, duration: float, wind: dict, estimator: str = "perfect") -> dict:
    """The HAPS on a straight leg north at ``altitude`` [m], ``tas`` [m/s]."""
    return {
        "name": "haps_leg",
        "seed": 3,
        "duration": duration,
        "origin": {"lat": 47.0, "lon": 8.0, "altitude": 0.0},
        "logging": {"rate_hz": 2},
        "wind": wind,
        "vehicle": [
            {
                "name": "haps",
                "aircraft": "haps",
                "estimator": estimator,
                "initial": {"altitude": altitude, "airspeed": tas, "heading": 0.0},
                "mission": {
                    "cruise_speed": tas,
                    "acceptance_radius": 250.0,
                    "waypoints": [{"north": 60000.0, "east": 0.0, "altitude": altitude}],
                },
            }
        ],
    }


def _truth(log: RunLog, name: str, after: float) -> dict[str, np.ndarray]:
    tr = log.topic(f"/{name}/truth/state")
    keep = tr.t >= after
    keys = ("pos_ned", "vel_ned", "euler", "tas_mps", "alt_msl_m", "alpha_rad", "beta_rad")
    return {"t": tr.t[keep]} | {k: np.asarray(tr[k])[keep] for k in keys}


def _air_wind(s: dict[str, np.ndarray]) -> np.ndarray:
    """The wind the truth implies, NED [m/s]: ground velocity - air velocity (TAS along the
    body's air-relative direction given by alpha and beta)."""
    from sim.core.frames import euler_to_dcm

    a, b, v = s["alpha_rad"], s["beta_rad"], s["tas_mps"]
    body = np.column_stack([v * np.cos(a) * np.cos(b), v * np.sin(b), v * np.sin(a) * np.cos(b)])
    air = np.array([euler_to_dcm(*e) @ u for e, u in zip(s["euler"], body, strict=True)])
    return s["vel_ned"] - air


@pytest.mark.closed_loop
def test_haps_crabs_into_a_steady_crosswind_by_the_wind_triangle(tmp_path):
    crosswind, tas = 15.0, 30.0
    log = _run(tmp_path, _haps_leg(20000.0, tas, 240.0, {"east": crosswind}))
    s = _truth(log, "haps", 150.0)  # after the turn onto the leg's line
    track = np.arctan2(s["vel_ned"][:, 1], s["vel_ned"][:, 0])
    heading = s["euler"][:, 2]
    assert np.abs(np.degrees(track)).max() < 1.0  # it holds the leg (track north)
    crab = np.degrees(-heading)  # the wind blows from the west: the nose turns west of north
    expected = np.degrees(np.arcsin(crosswind / s["tas_mps"]))
    assert np.abs(crab - expected).max() < 1.0
    ground = np.hypot(s["vel_ned"][:, 0], s["vel_ned"][:, 1])
    triangle = np.sqrt(s["tas_mps"] ** 2 - crosswind**2)
    assert np.abs(ground - triangle).max() < 0.5
    assert np.abs(s["tas_mps"] - tas).max() < 1.0  # the air, not the ground, sets the airspeed


def _hover_in_wind(wind: dict, duration: float) -> dict:
    data = tomllib.loads((ROOT / "scenarios" / "quad_hover_offset.toml").read_text())
    data.update(duration=duration, wind=wind)
    v = data["vehicle"][0]
    v.pop("estimator")  # the default: sensors + EKF
    v["initial"].update(roll=0, pitch=0)
    return data


def _drag_balance_lean(altitude_m: float, airspeed: float) -> float:
    """Tilt [rad] at which the thrust's horizontal part balances the frame drag of the JSBSim
    model (DRAG = qbar * S * CD, aircraft/quadrotor/quadrotor.xml) in the US 1976 atmosphere."""
    import xml.etree.ElementTree as ET

    root = ET.parse(ROOT / "aircraft" / "quadrotor" / "quadrotor.xml").getroot()
    area = float(root.findtext("metrics/wingarea"))
    cd = float(root.findtext("aerodynamics/axis[@name='DRAG']/function/product/value"))
    mass = float(root.findtext("mass_balance/emptywt"))
    rho = 1.225 * (1.0 - 2.25577e-5 * altitude_m) ** 4.2559  # troposphere
    return math.atan(0.5 * rho * airspeed**2 * area * cd / (mass * 9.80665))


@pytest.mark.closed_loop
def test_hovering_quadrotor_leans_into_the_wind_by_the_drag_balance_angle(tmp_path):
    wind = np.array([3.0, 4.0])  # towards north-east, 5 m/s
    log = _run(tmp_path, _hover_in_wind({"north": wind[0], "east": wind[1]}, 40.0))
    s = _truth(log, "quad", 20.0)
    assert np.abs(s["pos_ned"][:, :2]).max() < 1.0  # it holds its point against the wind
    from sim.core.frames import euler_to_dcm

    up = np.array([-euler_to_dcm(*e)[:, 2] for e in s["euler"]])  # thrust direction, NED
    lean = up[:, :2].mean(axis=0)  # its horizontal part: points upwind
    angle = math.asin(float(np.linalg.norm(lean)))
    assert angle == pytest.approx(_drag_balance_lean(420.0, 5.0), rel=0.2)
    assert float(lean @ wind) / (np.linalg.norm(lean) * 5.0) < -0.99  # into the wind


@pytest.mark.closed_loop
def test_haps_climbing_through_the_standard_profile_flies_in_its_wind(tmp_path):
    data = _haps_leg(16500.0, 28.0, 900.0, {"standard": "midlatitude_jet"})
    data["vehicle"][0]["mission"]["waypoints"] = [{"north": 80000.0, "east": 0.0, "altitude": 19500.0}]
    s = _truth(_run(tmp_path, data), "haps", 0.0)
    assert s["alt_msl_m"][-1] - s["alt_msl_m"][0] > 600.0  # it climbs through the profile
    field = WindField(parse_scenario(data).wind)
    expected = np.array([field.at(h, t) for h, t in zip(s["alt_msl_m"], s["t"], strict=True)])
    assert expected[0, 1] - expected[-1, 1] > 2.0  # and the profile's wind changes on the way
    assert np.abs(_air_wind(s) - expected).max() < 0.05


def test_wind_field_interpolates_in_altitude_and_time():
    levels = [{"altitude": 1000.0, "north": 0.0, "east": 10.0}, {"altitude": 3000.0, "north": 4.0, "east": 0.0}]
    f = WindField(Wind(north=1.0, levels=levels))
    assert f.at(2000.0, 0.0) == pytest.approx([3.0, 5.0, 0.0])
    assert f.at(0.0, 0.0) == pytest.approx([1.0, 10.0, 0.0])  # held below the table
    assert f.at(9000.0, 0.0) == pytest.approx([5.0, 0.0, 0.0])  # and above it
    assert f.max_shear() == pytest.approx(math.hypot(4.0, 10.0) / 2000.0)
    later = [{"altitude": 1000.0, "north": 0.0, "east": 20.0}, {"altitude": 3000.0, "north": 8.0, "east": 0.0}]
    f = WindField(Wind(hours=[{"time": 0.0, "levels": levels}, {"time": "1 h", "levels": later}]))
    assert f.at(1000.0, 1800.0) == pytest.approx([0.0, 15.0, 0.0])
    assert f.at(2000.0, 7200.0) == pytest.approx([4.0, 10.0, 0.0])


def test_standard_profile_has_its_jet_maximum_at_11_to_12_km():
    f = WindField(Wind(standard="midlatitude_jet"))
    alts = np.arange(0.0, 30001.0, 100.0)
    speed = np.array([np.linalg.norm(f.at(h, 0.0)) for h in alts])
    top = alts[speed == speed.max()]
    assert top.min() >= 11000.0 and top.max() <= 12000.0
    assert len(STANDARD_PROFILES) == 1


@pytest.mark.parametrize(
    ("wind", "message"),
    [
        ({"levels": [{"altitude": 2000.0}, {"altitude": 1000.0}]}, "wind.levels: altitudes must increase"),
        ({"levels": [{"altitude": 2000.0}]}, "wind.levels: a profile needs at least 2 levels"),
        ({"standard": "midlatitude_jet", "levels": [{"altitude": 0}, {"altitude": 1}]}, "give one wind profile"),
        ({"standard": "tropical"}, "wind.standard"),
        ({"hours": [{"time": 60, "levels": [{"altitude": 0}, {"altitude": 1}]}] * 2}, "times must increase"),
    ],
)
def test_bad_wind_profiles_are_field_named_errors(wind, message):
    data = _haps_leg(18000.0, 26.0, 10.0, wind)
    with pytest.raises(ScenarioError, match=message):
        parse_scenario(data)
