"""The thesis's chapter-6 scenarios rebuilt on synthetic storms (seed 002, 6.1, 6.3, 6.4).

Frames/units: local-level NED [m] from the thesis's origin 47.50 N, 10.25 E; times [s] from the
nowcast issue t0 (19:05 UTC in the thesis). Start, goal, initial course, dt, |dchi_max| and eps
are the thesis's (Tables 6.1, 6.9, 6.18, 6.19, 6.20); the Rad-TRAM storms of 27 June 2015 are not
available, so each scenario gets a seeded synthetic storm field with the character the thesis
describes: cells between start and goal moving at 6-18 m/s on courses around 110 deg, towards
the aircraft (6.1), a cell over the goal that drifts off it after about half an hour (6.3).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from shapely.geometry import Polygon

from guidance.mptp.config import MptpConfig
from guidance.mptp.goal import GoalTrack
from sim.geodesy import GeoPoint, geodetic_to_ned
from sim.storm_synthetic import StormField

ORIGIN = GeoPoint(47.50, 10.25)
STORM_COURSE = math.radians(110.0)


def ne(lat: float, lon: float) -> np.ndarray:
    return geodetic_to_ned(lat, lon, 0.0, ORIGIN)[:2]


def mission_area() -> Polygon:
    """47.50-50.00 N x 10.25-14.00 E as a polygon in (north, east) [m] (edges densified)."""
    s = np.linspace(0.0, 1.0, 25)
    lat = np.concatenate([47.5 + 0 * s, 47.5 + 2.5 * s, 50.0 + 0 * s, 50.0 - 2.5 * s])
    lon = np.concatenate([10.25 + 3.75 * s, 14.0 + 0 * s, 14.0 - 3.75 * s, 10.25 + 0 * s])
    return Polygon(geodetic_to_ned(lat, lon, 0.0, ORIGIN)[:, :2])


@dataclass(frozen=True)
class Scenario:
    name: str
    start: np.ndarray  # (north, east) [m]
    course: float  # initial course [rad]
    goal: GoalTrack
    cfg: MptpConfig
    storms: StormField
    iterations: int  # MPTP iterations of the thesis's run


def _storms(
    seed: int, centres_km: Sequence[tuple[float, float]], speed: float = 10.0, radius_km: float = 7.0
) -> StormField:
    v = speed * np.array([math.cos(STORM_COURSE), math.sin(STORM_COURSE)])
    return StormField(
        seed=seed,
        n_cells=len(centres_km),
        mean_velocity=tuple(v),
        speed_spread=2.5,
        mean_radius_m=radius_km * 1000.0,
        life_s=4 * 3600.0,
        split_prob=0.3,
        centres=np.array(centres_km) * 1000.0,
        births_after_t0=False,
    )


def _thesis(**changes) -> MptpConfig:
    return MptpConfig.thesis(mission_area=mission_area(), **changes)


def scenario_1(heuristic: str = "ssph", turning: str = "both") -> Scenario:
    """Continuous avoidance 1 (Table 6.1): dt 100 s, |dchi| 45 deg, eps 0.022 deg."""
    cells = [(120, 200), (150, 195), (178, 190), (205, 185), (135, 165), (190, 160), (230, 175)]
    return Scenario(
        "scenario 1",
        ne(48.83, 13.54),
        math.radians(280.0),
        GoalTrack.fixed(ne(49.01, 11.98)),
        _thesis(heuristic=heuristic, turning=turning),
        _storms(1, cells),
        10,
    )


def scenario_2(heuristic: str = "ssph", turning: str = "both") -> Scenario:
    """Continuous avoidance 2 (Table 6.9): dt 100 s, |dchi| 84 deg, eps 0.031 deg."""
    cells = [(95, 225), (120, 215), (145, 205), (105, 185), (140, 170), (165, 150), (80, 200), (175, 185)]
    eps = 0.031 * math.pi / 180 * 6_371_000.0
    return Scenario(
        "scenario 2",
        ne(48.154, 13.868),
        math.radians(205.0),
        GoalTrack.fixed(ne(49.006, 11.980)),
        _thesis(heuristic=heuristic, turning=turning, course_change_max=math.radians(84.0), simplify_tol_m=eps),
        _storms(2, cells),
        10,
    )


def holding_scenario(heuristic: str = "edh") -> Scenario:
    """Automatic holding (Table 6.18): dt 60 s; a cell sits on the goal and drifts off."""
    g = ne(49.006, 11.980)
    cells = [(g[0] / 1000, g[1] / 1000)]
    field = StormField(
        seed=3,
        n_cells=1,
        mean_velocity=(-6.0, -6.5),
        speed_spread=0.0,
        mean_radius_m=3000.0,
        life_s=6 * 3600.0,
        split_prob=0.0,
        centres=np.array(cells) * 1000.0,
        births_after_t0=False,
    )
    return Scenario(
        "holding",
        ne(49.134, 12.168),
        math.radians(220.0),
        GoalTrack.fixed(g),
        _thesis(heuristic=heuristic, dt_s=60.0),
        field,
        12,
    )


GOAL_TRACK_620 = [
    (0, 49.006, 11.980),
    (5, 48.957, 11.896),
    (10, 48.948, 11.776),
    (15, 48.903, 11.750),
    (20, 48.858, 11.723),
    (25, 48.804, 11.697),
    (30, 48.786, 11.657),
    (35, 48.732, 11.604),
    (40, 48.696, 11.537),
    (45, 48.678, 11.511),
    (50, 48.651, 11.484),
    (55, 48.606, 11.471),
    (60, 48.597, 11.405),
]


def moving_goal_scenario(heuristic: str = "edh") -> Scenario:
    """Moving goal (Tables 6.19, 6.20): dt 30 s, start and storms of scenario 2."""
    track = np.array(GOAL_TRACK_620)
    goal = GoalTrack(track[:, 0] * 60.0, np.array([ne(la, lo) for _, la, lo in track]))
    base = scenario_2()
    return Scenario(
        "moving goal", base.start, base.course, goal, _thesis(heuristic=heuristic, dt_s=30.0), base.storms, 10
    )
