"""Planner parameters of the MPTP, with the HAPS defaults and the thesis's 80 m/s aircraft.

Units SI, angles in radians (the ``*_deg`` constructors are for people). The aircraft model is
the thesis's low-fidelity one (seed 002, 3.2 and 5.1): constant true airspeed in the air-mass
frame (wind.py; ground speed = airspeed in still air), level flight, course changes of at most
``course_change_max`` per state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np
from shapely.geometry import Polygon

from sim.core.constants import STANDARD_GRAVITY

NM = 1852.0  # m per nautical mile

Heuristic = Literal["dijkstra", "edh", "ssph"]
WindSource = Literal["scenario", "none", "estimate"]
SpeedSource = Literal["estimate", "config"]
Turning = Literal["both", "right", "left"]
TurnModelName = Literal["simple", "approximate", "simulated"]


@dataclass(frozen=True, slots=True)
class MptpConfig:
    """Everything one replan depends on besides the nowcast and the states.

    Aircraft: ``tas_mps`` planning speed [m/s] (``speed_source`` "estimate": each replan plans at
    the estimate's true airspeed instead, ``tas_mps`` only while it has none; "config": always
    ``tas_mps``, the thesis's constant-speed model); ``bank_max`` [rad]; ``course_change_max`` the
    largest course change at one state [rad] (thesis |dchi_max|); ``dt_s`` planning time
    increment [s] (auxiliary-state leg = tas * dt; a divisor of the nowcast step keeps levels
    on nowcast times); ``horizon_s`` planning horizon T_P [s]; ``replan_period_s`` cadence [s].

    Turns (turnmodel.py): ``turn_model`` "simple" = fly-by states with the simple auxiliary
    states of seed 002 5.1; "approximate" = fly-over states, the turn a circular arc at the bank
    limit (5.2); "simulated" = fly-over states, the turn simulated with the bank slewed at
    ``roll_rate_max`` [rad/s] to and from the bank limit (5.3; default 6 deg/s, the HAPS's
    bank-command slew limit in aircraft/haps/gains.toml). Both fly-over models plan their turns
    at ``turn_bank_fraction`` * bank_max (turn_bank_rad), leaving the follower the rest of its
    bank limit to make up its roll lag and look-ahead (the thesis states no reserve; the default
    0.75 turns the HAPS, bank-command limit 20 deg, at the 15 deg of the thesis's HAPS, eq. 5.53).
    ``start_lead_s`` [s] >= 0: each replan searches from the state predicted this far past its
    issue, the current turn held, and flies that prediction as the plan's first leg (lead_in.py),
    so that the follower can lead the plan's first turn; the engine sets it to the airframe's
    follower turn lead (``l1_turn_lead_s``) for the fly-over models and 0 for the simple one
    unless the scenario gives it (on a real aircraft add the planning latency).

    Search: ``heuristic``; ``turning`` sense(s) of the auxiliary states; ``max_expansions``
    caps A* (the thesis's Monte-Carlo success criterion used 100, its chapter-6 runs here 120;
    the HAPS default 400 lets a search find a wait for a passage that opens 20 min on, which
    took up to 393 expansions in scenarios/mptp/corridor_opens.toml on seeds 1-20); ``search_weight`` w >= 1
    orders the open list by G + w H (weighted A*: at most w times the optimum with a consistent
    admissible H; w > 1 leaves the plateaus that waiting creates early); ``dominance_s`` [s]:
    a place and course is expanded once per window of this length, at its earliest arrival
    (search.py); ``wait_step_min_s`` [s]: the wait bound's time step (waitbound.py) is dt split
    into at most 3 substeps no shorter than this (``wait_substeps``): its cost grows with the
    cube of the substeps per second, so a small dt (30 s) gets one (tau = dt) instead of three.

    Margins (seed 002 3.1): probabilistic radius r = sqrt(-2 ln(1-P)) * sigma(theta) * lead_time,
    sigma from ``sigma_back_mps`` (against the motion) to ``sigma_front_mps`` (along it), capped
    at ``prob_margin_max_m``; safety margins [m] by cell speed band (<10, <20, >=20 m/s) for a
    single cell and a line of storms (aspect ratio >= ``line_aspect``); both added (ch. 6
    "sum of safety and probabilistic margins"). ``probabilities``: several P levels planned
    for, the feasible plan of the largest P flown (3.1.1 end); empty = ``probability`` alone.
    ``safety_area_steps``: rows [area [km^2], extra [m]] with increasing area, the extra of
    the largest step at or below a cell's area added to its safety margin (3.1.2: the margin
    grows with a cell's size). ``downwind_factor`` >= 1: the safety margin on the downwind
    side of a cell over the one on its upwind side (3.1.2: turbulence and hail are met
    downwind), the wind being the planner's forecast or, in still air, the cell's motion.
    ``cluster_eps_m`` > 0 closes passages narrower than it (3.1.4); ``simplify_tol_m`` is the
    Douglas-Peucker tolerance, added to the margins first so that smoothing never undercuts
    them (Fig. 4.3).

    Holding (5.4): ``hold_speed_correction`` flies a holding orbit on the circumcircle of its
    n-gon of fly-over states at V_cor = V dV(n) (eq. 5.78), so each state is reached after dt;
    ``holding_points``: pre-defined holding locations [[north, east], ...] [m], used (nearest
    first) when the goal is covered over the whole horizon and the orbit there is free.

    ``mission_area``: where the aircraft may fly, (north, east) [m], a Polygon or its exterior
    vertices [[north, east], ...] (scenario files); None = unrestricted (the workspace is then the
    start-goal box padded by half the horizon's range).

    ``goal_track``: a predicted track of a moving goal that replaces the mission waypoint as the
    target, rows [t [s], north [m], east [m]] with increasing t (the thesis's 6.4); None = the
    mission waypoint.

    Wind (read by the engine when it builds the planner, see wind.py): ``wind_forecast``
    "scenario" = the planner is given the scenario's wind (steady, profile or hourly tables)
    plus ``wind_error_ne_mps`` (north, east) [m/s] as its forecast; "none" = still air
    (wind-blind planning); "estimate" = the wind the navigation estimate implies, measured by
    the planner itself: the mean over the last ``replan_period_s`` of the ground velocity minus
    the air velocity (the TAS along the estimated heading, sideslip neglected), taken steady at
    every height (no forecast, no ``wind_error_ne_mps``).

    Navigation (planner.py): the first plan waits, flying straight on, while the estimate's
    horizontal position sigma (the larger of its N and E 1-sigma) is above ``nav_std_max_m`` [m]
    (> 0; inf never waits), at most one ``replan_period_s``: a plan made on the EKF's initial
    alignment (3 m per axis) turns where the first GNSS fix moves the estimate by metres.

    Plan keeping (keeping.py): a replan flies on the current plan while it reaches the goal, the
    aircraft is within ``keep_within_m`` [m] of where the plan has it now, the rest of the plan is
    clear of the new nowcast, and the new plan would not arrive earlier by more than
    ``keep_slack`` (a fraction) of the remaining flight time; ``keep_within_m`` = 0 replaces the
    plan at every replan.

    Storm tops (vertical.py): a cell is avoided while the heights the aircraft can reach over the
    horizon, climbing or descending towards the goal at up to ``climb_rate_mps`` [m/s], come
    within ``vertical_margin_m`` [m] of the cell's base-to-top extent.
    """

    tas_mps: float = 26.0
    bank_max: float = math.radians(20.0)
    course_change_max: float = math.radians(45.0)
    dt_s: float = 60.0
    horizon_s: float = 3600.0
    replan_period_s: float = 300.0
    heuristic: Heuristic = "ssph"
    turning: Turning = "both"
    turn_model: TurnModelName = "simple"
    roll_rate_max: float = math.radians(6.0)
    turn_bank_fraction: float = 0.75
    start_lead_s: float = 0.0
    max_expansions: int = 400
    search_weight: float = 1.1
    dominance_s: float = 240.0
    wait_step_min_s: float = 20.0
    probability: float = 0.9
    probabilities: tuple[float, ...] = ()
    sigma_front_mps: float = 1.5
    sigma_back_mps: float = 0.75
    prob_margin_max_m: float = 15_000.0
    safety_single_m: tuple[float, float, float] = (5_000.0, 6_000.0, 8_000.0)
    safety_line_m: tuple[float, float, float] = (8_000.0, 9_000.0, 10_000.0)
    line_aspect: float = 3.0
    safety_area_steps: tuple[tuple[float, float], ...] = ()
    downwind_factor: float = 1.0
    cluster_eps_m: float = 0.0
    simplify_tol_m: float = 200.0
    ring_segments: int = 72
    hold_speed_correction: bool = False
    holding_points: tuple[tuple[float, float], ...] = ()
    mission_area: Polygon | None = None
    goal_track: tuple[tuple[float, float, float], ...] | None = None
    g: float = STANDARD_GRAVITY
    wind_forecast: WindSource = "scenario"
    wind_error_ne_mps: tuple[float, float] = (0.0, 0.0)
    vertical_margin_m: float = 1000.0
    climb_rate_mps: float = 1.0
    speed_source: SpeedSource = "estimate"
    keep_within_m: float = 500.0
    keep_slack: float = 0.02
    nav_std_max_m: float = 1.5

    def __post_init__(self) -> None:
        if self.tas_mps <= 0 or self.dt_s <= 0 or self.horizon_s < self.dt_s:
            raise ValueError("need tas_mps > 0, dt_s > 0 and horizon_s >= dt_s")
        if not 0 < self.bank_max < math.pi / 2 or not 0 < self.course_change_max <= math.pi / 2:
            raise ValueError("bank_max must be in (0, 90) deg and course_change_max in (0, 90] deg")
        if not self.search_weight >= 1.0 or not self.dominance_s > 0 or not self.wait_step_min_s > 0:
            raise ValueError("need search_weight >= 1, dominance_s > 0 and wait_step_min_s > 0")
        if not self.keep_within_m >= 0 or not 0 <= self.keep_slack < 1:
            raise ValueError("need keep_within_m >= 0 and keep_slack in [0, 1)")
        if not self.nav_std_max_m > 0:
            raise ValueError(f"nav_std_max_m must be > 0 [m], got {self.nav_std_max_m}")
        if not self.vertical_margin_m >= 0 or not self.climb_rate_mps >= 0:
            raise ValueError("need vertical_margin_m >= 0 and climb_rate_mps >= 0")
        if not 0 <= self.probability < 1:
            raise ValueError("probability must be in [0, 1)")
        levels = _rows(self.probabilities, 0, "probabilities: expected a list of P in [0, 1)")
        if not all(0 <= p < 1 for p in levels):
            raise ValueError("probabilities: expected a list of P in [0, 1)")
        object.__setattr__(self, "probabilities", tuple(float(p) for p in levels))
        steps = _rows(self.safety_area_steps, 2, "safety_area_steps: expected rows [area km^2, extra m]")
        if len(steps) and (np.any(steps < 0) or np.any(np.diff(steps[:, 0]) <= 0)):
            raise ValueError("safety_area_steps: expected rows [area km^2, extra m] >= 0 with increasing area")
        object.__setattr__(self, "safety_area_steps", tuple(map(tuple, steps.tolist())))
        if not self.downwind_factor >= 1.0:
            raise ValueError(f"downwind_factor: expected >= 1, got {self.downwind_factor!r}")
        points = _rows(self.holding_points, 2, "holding_points: expected rows [north, east] [m]")
        object.__setattr__(self, "holding_points", tuple(map(tuple, points.tolist())))
        if self.heuristic not in ("dijkstra", "edh", "ssph") or self.turning not in ("both", "right", "left"):
            raise ValueError(f"unknown heuristic {self.heuristic!r} or turning {self.turning!r}")
        if self.speed_source not in ("estimate", "config"):
            raise ValueError(f"speed_source: expected 'estimate' or 'config', got {self.speed_source!r}")
        if self.turn_model not in ("simple", "approximate", "simulated"):
            raise ValueError(f"turn_model: expected 'simple', 'approximate' or 'simulated', got {self.turn_model!r}")
        if not self.roll_rate_max > 0:
            raise ValueError("roll_rate_max must be > 0 [rad/s]")
        if not 0 < self.turn_bank_fraction <= 1:
            raise ValueError(f"turn_bank_fraction must be in (0, 1], got {self.turn_bank_fraction}")
        if not self.start_lead_s >= 0:
            raise ValueError(f"start_lead_s must be >= 0 [s], got {self.start_lead_s}")
        if self.wind_forecast not in ("scenario", "none", "estimate"):
            raise ValueError(f"wind_forecast: expected 'scenario', 'none' or 'estimate', got {self.wind_forecast!r}")
        err = np.asarray(self.wind_error_ne_mps, float) if _is_numeric(self.wind_error_ne_mps) else np.empty(0)
        if err.shape != (2,) or not np.isfinite(err).all():
            raise ValueError("wind_error_ne_mps: expected [north, east] [m/s]")
        object.__setattr__(self, "wind_error_ne_mps", (float(err[0]), float(err[1])))
        for name in ("safety_single_m", "safety_line_m"):  # lists from scenario files
            object.__setattr__(self, name, tuple(float(x) for x in getattr(self, name)))
        if self.mission_area is not None and not isinstance(self.mission_area, Polygon):
            object.__setattr__(self, "mission_area", _area(self.mission_area))
        if self.goal_track is not None:
            object.__setattr__(self, "goal_track", _track(self.goal_track))

    @property
    def turn_radius_m(self) -> float:
        """Minimum turn radius R = V^2 / (g tan(bank_max)) [m] (seed 002 eq. 5.67)."""
        return self.tas_mps**2 / (self.g * math.tan(self.bank_max))

    @property
    def turn_bank_rad(self) -> float:
        """Bank [rad] the fly-over turn models plan at: turn_bank_fraction * bank_max."""
        return self.turn_bank_fraction * self.bank_max

    @property
    def fly_over_radius_m(self) -> float:
        """Turn radius [m] of the fly-over models at turn_bank_rad: V^2 / (g tan(turn_bank_rad))."""
        return self.tas_mps**2 / (self.g * math.tan(self.turn_bank_rad))

    @property
    def probability_levels(self) -> tuple[float, ...]:
        """The P levels planned for, largest first (3.1.1)."""
        return tuple(sorted(set(self.probabilities or (self.probability,)), reverse=True))

    @property
    def leg_m(self) -> float:
        """Leg distance of an auxiliary state LD = V * dt [m]."""
        return self.tas_mps * self.dt_s

    @property
    def wait_substeps(self) -> int:
        """Time steps of the wait bound per planning interval: dt / wait_step_min_s, 1 to 3."""
        return int(min(3, max(1, math.floor(self.dt_s / self.wait_step_min_s))))

    def with_(self, **changes) -> MptpConfig:
        return replace(self, **changes)

    @classmethod
    def thesis(cls, **changes) -> MptpConfig:
        """The thesis's chapter-6 aircraft: 80 m/s, bank <= 25 deg, dt 100 s, |dchi| 45 deg,
        margins 10 km at issue growing to 35 km after one hour, eps 0.022 deg (~2.4 km)."""
        base = cls(
            tas_mps=80.0,
            bank_max=math.radians(25.0),
            course_change_max=math.radians(45.0),
            dt_s=100.0,
            horizon_s=3600.0,
            replan_period_s=300.0,
            max_expansions=120,
            probability=0.9,
            sigma_front_mps=25_000.0 / (math.sqrt(-2 * math.log(0.1)) * 3600.0),
            sigma_back_mps=12_500.0 / (math.sqrt(-2 * math.log(0.1)) * 3600.0),
            prob_margin_max_m=25_000.0,
            safety_single_m=(10_000.0,) * 3,
            safety_line_m=(10_000.0,) * 3,
            simplify_tol_m=0.022 * math.pi / 180 * 6_371_000.0,
        )
        return replace(base, **changes)


def _is_numeric(value) -> bool:
    try:
        np.asarray(value, float)
    except (TypeError, ValueError):
        return False
    return True


def _rows(value, width: int, message: str) -> np.ndarray:
    """``value`` as a finite float array: (N,) for width 0, else (N, width) (N may be 0)."""
    try:
        arr = np.asarray(value, float).reshape(-1) if width == 0 else np.asarray(value, float).reshape(-1, width)
    except (TypeError, ValueError):
        raise ValueError(message) from None
    if not np.isfinite(arr).all() or (width and np.ndim(value) != 2 and len(arr)):
        raise ValueError(message)
    return arr


def _area(vertices) -> Polygon:
    """A mission area from its exterior vertices [[north, east], ...] [m]."""
    try:
        pts = np.asarray(vertices, float)
        area = Polygon(pts) if pts.ndim == 2 and pts.shape[1] == 2 and len(pts) >= 3 else Polygon()
    except (TypeError, ValueError):
        area = Polygon()
    if area.is_empty or not area.is_valid or area.area <= 0:
        raise ValueError("mission_area: expected >= 3 vertices [[north, east], ...] [m] of a simple polygon")
    return area


def _track(rows) -> tuple[tuple[float, float, float], ...]:
    """A goal track from rows [t, north, east] [s, m, m] with increasing t."""
    try:
        arr = np.asarray(rows, float)
    except (TypeError, ValueError):
        arr = np.empty((0, 0))
    if (
        arr.ndim != 2
        or arr.shape[1] != 3
        or not len(arr)
        or not np.isfinite(arr).all()
        or np.any(np.diff(arr[:, 0]) <= 0)
    ):
        raise ValueError("goal_track: expected rows [t, north, east] [s, m, m] with increasing t")
    return tuple(map(tuple, arr.tolist()))
