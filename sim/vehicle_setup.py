"""Building one vehicle's parts from its scenario entry: the mission in the NED frame, the JSBSim
plant in its initial state (trimmed, in the scenario's wind), the estimator and the plan follower.
Frames: local-level NED from the scenario origin [m]; altitudes MSL [m]."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from aircraft.registry import Airframe, resolve
from guidance.fixed_wing_follower import FixedWingPlanFollower
from guidance.l1 import L1Guidance
from guidance.multirotor_follower import MultirotorPlanFollower
from sim import scenario as sc
from sim.core.mission import Mission
from sim.core.plan import Planner
from sim.environment import apply_turbulence
from sim.estimation.sensor_estimator import SensorEstimator
from sim.estimator import PerfectEstimator
from sim.geodesy import GeoPoint, ned_to_geodetic
from sim.jsbsim_plant import InitialConditions, JSBSimPlant, PlantError
from sim.planner_registry import make_planner
from sim.wind_field import WindField


def ned_of(north: float, east: float, altitude: float, origin: GeoPoint) -> np.ndarray:
    """NED [m] of a scenario position (north/east offsets [m], altitude MSL [m])."""
    return np.array([north, east, origin.alt_m - altitude])


def mission_from_config(cfg: sc.VehicleSpec, origin: GeoPoint) -> Mission:
    """The vehicle's mission in the local-level NED frame, starting at its initial position."""
    m, ini = cfg.mission, cfg.initial
    return Mission(
        waypoints=np.array([ned_of(w.north, w.east, w.altitude, origin) for w in m.waypoints]),
        cruise_speed=m.cruise_speed,
        acceptance_radius=m.acceptance_radius,
        start=ned_of(ini.north, ini.east, ini.altitude, origin),
        hold_s={k: w.hold for k, w in enumerate(m.waypoints) if w.hold > 0},
        land=m.land,
    )


def scenario_planner(
    cfg: sc.VehicleSpec, mission: Mission, af: Airframe, gains: object, wind: sc.Wind, origin_alt_m: float
) -> Planner:
    """The scenario's planner for ``mission``; a fixed-wing planner turns within the controller's
    roll limit (``gains.roll_limit_rad`` [rad], 20 deg for gains without one) at its bank-command
    slew rate (``gains.roll_rate_limit_rad_s`` [rad/s], when it has one) and knows its
    follower's turn lead (``gains.l1_turn_lead_s`` [s], 0 without one); the planners'
    wind forecast is the scenario's ``wind``: its steady (north, east) [m/s] and, when it varies
    with altitude or time, its profile in height above the origin (``origin_alt_m`` [m MSL]) and
    time."""
    roll_limit = float(getattr(gains, "roll_limit_rad", math.radians(20.0)))
    lead = float(getattr(gains, "l1_turn_lead_s", 0.0))
    roll_rate = getattr(gains, "roll_rate_limit_rad_s", None)
    profile = WindField(wind).forecast_rows(origin_alt_m)
    return make_planner(
        cfg.planner.type,
        mission,
        af.kind,
        cfg.planner.options,
        roll_limit,
        (wind.north, wind.east),
        profile,
        lead,
        None if roll_rate is None else float(roll_rate),
    )


def trim_plant(plant: JSBSimPlant, af: Airframe, note: Callable[[str], None]) -> None:
    """JSBSim's trim; where it fails (the HAPS below ~13 km, see sim/tuning/trim_haps.py) the
    airframe's own level-flight trim, told to ``note``."""
    try:
        plant.trim()
    except PlantError as exc:
        if af.level_trim is None:
            raise
        resolve(af.level_trim)(plant)
        note(f"JSBSim trim failed ({exc}); level-flight trim used")


def build_plant(
    cfg: sc.VehicleSpec,
    af: Airframe,
    origin: GeoPoint,
    wind: sc.Wind,
    wind_field: WindField,
    seed: int,
    note: Callable[[str], None] = lambda text: None,
) -> JSBSimPlant:
    """The JSBSim plant at the scenario's initial state: initial conditions, trim (fixed wing by
    default; ``note`` hears of a fallback trim), the wind at the start altitude with the initial
    airspeed relative to the air (on the ground: ground velocity zero), turbulence seeded with
    the vehicle's ``seed``."""
    plant = JSBSimPlant(af.jsbsim_model, 1.0 / af.plant_hz, origin, af.folder)
    ini = cfg.initial
    lat, lon, alt = ned_to_geodetic(ned_of(ini.north, ini.east, ini.altitude, origin), origin)
    plant.initialise(
        InitialConditions(
            position=GeoPoint(float(lat), float(lon), float(alt)),
            tas_mps=ini.airspeed,
            heading_rad=ini.heading,
            roll_rad=ini.roll,
            pitch_rad=ini.pitch,
            on_ground=ini.on_ground,
            terrain_alt_m=origin.alt_m,
        )
    )
    if ini.trim if ini.trim is not None else af.kind == "fixed_wing":
        trim_plant(plant, af, note)
    w = wind_field.at(float(alt), 0.0)
    if ini.on_ground:
        plant.set_wind(w)
    elif np.any(w):  # calm air: the initialised state stands as it is
        plant.carry_into_wind(w)
    apply_turbulence(plant, wind, seed)
    return plant


def make_estimator(kind: str, plant: JSBSimPlant, af: Airframe, seed: int, origin: GeoPoint, sensors: sc.SensorsSpec):
    """``ekf``: the scenario's sensor models + INS/GNSS EKF (the default: the loop closes on
    estimates); ``perfect``: ideal sensors (controller characterisation against the model)."""
    if kind == "perfect":
        return PerfectEstimator(plant)
    cfg = sensors.estimator_config(af.kind)
    cfg.check_rates(af.plant_hz)
    rng = np.random.default_rng(np.random.SeedSequence([seed, 1]))  # not the turbulence stream
    return SensorEstimator(plant, cfg, rng, origin, plant.truth())


def make_follower(cfg: sc.VehicleSpec, af: Airframe, controller, mission: Mission, origin: GeoPoint):
    """The plan follower of the airframe kind: L1 + altitude/speed demands (fixed wing) or
    position/velocity setpoints along the plan (multirotor)."""
    m = cfg.mission
    if af.kind == "fixed_wing":
        return FixedWingPlanFollower(
            L1Guidance.for_airframe(controller), m.cruise_speed, m.acceptance_radius, origin.alt_m
        )
    lim = controller.gains.limits
    return MultirotorPlanFollower(
        m.cruise_speed,
        lim.max_climb,
        lim.max_descent,
        m.acceptance_radius,
        mission.hold_s,
        yaw_rad={k: w.yaw for k, w in enumerate(m.waypoints) if w.yaw is not None},
        step=m.guidance == "step",
    )
