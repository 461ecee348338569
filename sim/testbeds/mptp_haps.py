"""The thesis's scenarios (scenarios.py) as closed-loop scenarios of the JSBSim HAPS.

The thesis's aircraft flies at 80 m/s with a 1.40 km turn radius, the HAPS at 26 m/s with
189 m (20 deg bank). A scenario is mapped with a space scale s and a time scale
tau = s * V_thesis / V_haps: every length (positions, storm sizes, margins, tolerances, mission
area) is multiplied by s, every time (dt, horizon, replan period, nowcast step and period, cell
lives, goal-track times) by tau and every speed (storm drift and spread, margin growth sigma) by
s / tau = V_haps / V_thesis. The storm field keeps its seed, so the cells have the same shapes,
the same relative motion and the same splits as in the open-loop scenario. This keeps the
geometry (storms, margins and legs against the distances) and the speed ratio of storms to
aircraft. The turn radius is the HAPS's own; it keeps the thesis's ratio to the storm sizes only
for s = R_haps / R_thesis (0.135, "matched": ~25 km, ~20 min of flight, the CI size); s = 1 keeps
the thesis's distances (~200 km, ~2 h of flight; "full size").

Frames/units of the result: a scenario-file dict (sim.scenario) in SI units, local-level NED [m]
from the thesis's origin 47.50 N, 10.25 E; the HAPS at 18 km.
"""

from __future__ import annotations

import math

import numpy as np

from aircraft.haps.gains import HapsGains
from guidance.mptp.config import MptpConfig
from sim.testbeds.mptp_thesis import ORIGIN, Scenario

ALTITUDE_M = 18_000.0
HAPS_TAS_MPS = 26.0
# config fields by how they scale: lengths (x s), times (x tau), speeds (x s / tau), unchanged
_LENGTHS = ("prob_margin_max_m", "cluster_eps_m", "simplify_tol_m")
_TIMES = ("dt_s", "horizon_s", "replan_period_s")
_SPEEDS = ("sigma_front_mps", "sigma_back_mps")
_SAME = ("course_change_max", "heuristic", "turning", "max_expansions", "probability", "line_aspect", "ring_segments")
NOWCAST_STEP_S = 300.0  # the thesis's Rad-TRAM step and issue period [s]


def haps_config() -> MptpConfig:
    """The MPTP aircraft parameters of the HAPS (speed, the autopilot's bank limit)."""
    bank = HapsGains.load().roll_limit_rad
    return MptpConfig(tas_mps=HAPS_TAS_MPS, bank_max=bank)


def matched_scale(sc: Scenario) -> float:
    """Space scale that keeps the thesis's turn radius relative to the storms (R_haps / R)."""
    return haps_config().turn_radius_m / sc.cfg.turn_radius_m


def time_scale(sc: Scenario, space_scale: float) -> float:
    """tau = s * V_thesis / V_haps."""
    return space_scale * sc.cfg.tas_mps / HAPS_TAS_MPS


def scenario_data(sc: Scenario, space_scale: float, seed: int = 1) -> dict:
    """The scenario-file dict of ``sc`` flown by the HAPS, scaled by ``space_scale``.

    Duration: the thesis's replanning iterations plus 30 min, scaled (the run stops when the
    goal is reached)."""
    s = float(space_scale)
    tau = time_scale(sc, s)
    v = s / tau
    cfg, f = sc.cfg, sc.storms
    options: dict = {k: getattr(cfg, k) for k in _SAME}
    options.update({k: getattr(cfg, k) * s for k in _LENGTHS})
    options.update({k: getattr(cfg, k) * tau for k in _TIMES})
    options.update({k: getattr(cfg, k) * v for k in _SPEEDS})
    options["safety_single_m"] = [x * s for x in cfg.safety_single_m]
    options["safety_line_m"] = [x * s for x in cfg.safety_line_m]
    if cfg.mission_area is not None:
        options["mission_area"] = (np.asarray(cfg.mission_area.exterior.coords)[:-1] * s).tolist()
    goal0 = sc.goal.at(0.0) * s
    if sc.goal.moving:
        options["goal_track"] = np.column_stack([sc.goal.times * tau, sc.goal.points * s]).tolist()
    weather = {
        "seed": f.seed,
        "pop_up": f.births_after_t0,
        "cells": f.n_cells,
        "size": f.size_m[0] * s,
        "drift_north": f.mean_velocity[0] * v,
        "drift_east": f.mean_velocity[1] * v,
        "drift_spread": f.speed_spread * v,
        "radius": f.mean_radius_m * s,
        "split_probability": f.split_prob,
        "life": f.life_s * tau,
        "nowcast_period": NOWCAST_STEP_S * tau,
        "step": NOWCAST_STEP_S * tau,
        "horizon": cfg.horizon_s * tau,
        "centres": (np.asarray(f.centres) * s).tolist(),
    }
    start = sc.start * s
    # legs switch at the fly-by turn's anticipation distance (the follower's acceptance radius)
    accept = max(100.0, haps_config().turn_radius_m * math.tan(0.5 * cfg.course_change_max))
    duration = tau * (sc.iterations * cfg.replan_period_s + 1800.0)
    return {
        "name": f"mptp_{sc.name.replace(' ', '_')}_x{s:.3g}",
        "description": f"MPTP thesis {sc.name} ({cfg.heuristic}, {cfg.turning} turns), HAPS, space x{s:.3g}, "
        f"time x{tau:.3g}",
        "seed": seed,
        "duration": duration,
        "origin": {"lat": ORIGIN.lat_deg, "lon": ORIGIN.lon_deg, "altitude": 0.0},
        "weather": weather,
        "vehicle": [
            {
                "name": "haps",
                "aircraft": "haps",
                "initial": {
                    "north": float(start[0]),
                    "east": float(start[1]),
                    "altitude": ALTITUDE_M,
                    "airspeed": HAPS_TAS_MPS,
                    "heading": math.degrees(sc.course) % 360.0,
                },
                "mission": {
                    "cruise_speed": HAPS_TAS_MPS,
                    "acceptance_radius": round(accept, 1),
                    "waypoints": [{"north": float(goal0[0]), "east": float(goal0[1]), "altitude": ALTITUDE_M}],
                },
                "planner": {"type": "mptp", "rate_hz": 0.1, "options": options},
            }
        ],
    }
