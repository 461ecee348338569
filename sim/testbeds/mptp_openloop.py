"""Open-loop replanning runs as in the thesis's chapter 6 (no aircraft model).

Frames/units: (north, east) [m], times [s]. The MPTP is called every ``replan_period_s`` with a
fresh nowcast of the storm field; the aircraft is assumed to reach the commanded states in due
time (6.1), so the next initial state is the state on the current plan one period later. The
flown trajectory is the composite of the first period of every plan. In a true wind the
aircraft flies the plan's ground legs at the planning TAS, crabbed, at the times that wind
gives (a kinematic aircraft, no turn dynamics). Closed-loop flight with JSBSim uses the same
MptpPlanner through the runner.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from guidance.mptp.goal import GoalTrack
from guidance.mptp.planner import MptpPlanner
from guidance.mptp.wind import WindForecast
from sim.core.mission import Mission
from sim.core.plan import Plan, PlanStatus, Threats
from sim.core.state import VehicleState
from sim.testbeds.mptp_thesis import Scenario


@dataclass
class OpenLoopRun:
    plans: list[Plan] = field(default_factory=list)
    start_courses: list[float] = field(default_factory=list)  # the course each plan starts from [rad]
    flown_ne: np.ndarray = field(default_factory=lambda: np.empty((0, 2)))  # (M, 2) [m]
    flown_t: np.ndarray = field(default_factory=lambda: np.empty(0))  # (M,) [s]
    arrived_s: float = float("nan")

    @property
    def length_m(self) -> float:
        return float(np.linalg.norm(np.diff(self.flown_ne, axis=0), axis=1).sum())


def state_on(times: np.ndarray, ne: np.ndarray, t: float) -> tuple[np.ndarray, float]:
    """Position (north, east) [m] and ground course [rad] at time t on legs ``ne`` (N, 2) [m]
    reached at ``times`` (N,) [s]."""
    if len(times) == 1:
        return ne[0].copy(), 0.0
    k = int(np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 2))
    s = np.clip((t - times[k]) / max(times[k + 1] - times[k], 1e-9), 0.0, 1.0)
    d = ne[k + 1] - ne[k]
    return ne[k] + s * d, float(np.arctan2(d[1], d[0]))


def ground_speed(course: np.ndarray | float, tas: float, wind_ne: np.ndarray) -> np.ndarray:
    """Ground speed [m/s] on ground course(s) [rad] at ``tas`` [m/s] in ``wind_ne`` [m/s], the
    heading crabbed into the cross wind: w.u + sqrt(V^2 - (w x u)^2)."""
    u = np.stack([np.cos(course), np.sin(course)], -1)
    along = u @ wind_ne
    cross = u[..., 0] * wind_ne[1] - u[..., 1] * wind_ne[0]
    return along + np.sqrt(tas**2 - cross**2)


def flown_times(ne: np.ndarray, t0: float, tas: float, wind_ne: np.ndarray) -> np.ndarray:
    """Times [s] at which legs ``ne`` (N, 2) [m] are flown from ``t0`` on the ground at ``tas``
    in ``wind_ne`` (straight legs, crabbed)."""
    d = np.diff(ne, axis=0)
    gs = ground_speed(np.arctan2(d[:, 1], d[:, 0]), tas, wind_ne)
    return t0 + np.concatenate([[0.0], np.cumsum(np.linalg.norm(d, axis=1) / gs)])


def vehicle_state(
    t: float, ne: np.ndarray, course: float, speed: float, wind_ne: np.ndarray | None = None
) -> VehicleState:
    """A level state at ``ne`` [m] on ground course ``course`` [rad] at true airspeed ``speed``
    [m/s] in ``wind_ne`` (None = still air)."""
    gs = speed if wind_ne is None else float(ground_speed(course, speed, np.asarray(wind_ne, float)))
    vel = gs * np.array([np.cos(course), np.sin(course), 0.0])
    return VehicleState(
        t=t,
        pos_ned=np.array([ne[0], ne[1], 0.0]),
        vel_ned=vel,
        euler=np.array([0.0, 0.0, course]),
        rates_body=np.zeros(3),
        alt_msl_m=0.0,
        lat_deg=0.0,
        lon_deg=0.0,
        tas_mps=speed,
    )


def run_open_loop(
    sc: Scenario,
    reactive_goal: bool = False,
    iterations: int | None = None,
    dense_step_s: float = 10.0,
    wind_true: np.ndarray | None = None,
    wind_forecast: WindForecast | None = None,
) -> OpenLoopRun:
    """Replan ``iterations`` times (default: the scenario's) or until the goal is reached.

    ``wind_true`` (north, east) [m/s]: the aircraft flies each plan's legs on the ground at
    the planning TAS in this wind (crabbed), at its own times rather than the plan's;
    ``wind_forecast``: the wind the planner is given (None = still air)."""
    cfg = sc.cfg
    g0 = sc.goal.at(0.0)
    mission = Mission(np.array([[g0[0], g0[1], 0.0]]), cfg.tas_mps, acceptance_radius=cfg.leg_m)
    planner = MptpPlanner(mission, cfg, None if reactive_goal or not sc.goal.moving else sc.goal, wind_forecast)
    run = OpenLoopRun()
    ne, course, t = sc.start.astype(float), sc.course, 0.0
    flown, flown_t = [], []
    for _ in range(iterations or sc.iterations):
        if reactive_goal:
            planner.goal_track = GoalTrack.fixed(sc.goal.at(t))
        threats = Threats(storms=sc.storms.nowcast(t, cfg.horizon_s))
        plan = planner.plan(vehicle_state(t, ne, course, cfg.tas_mps, wind_true), threats, t)
        run.plans.append(plan)
        run.start_courses.append(course)
        legs = plan.positions[:, :2]
        times = plan.times if wind_true is None else flown_times(legs, t, cfg.tas_mps, np.asarray(wind_true, float))
        t_next = t + cfg.replan_period_s
        arrive = plan.status != PlanStatus.NO_SOLUTION and (plan.labels >= 0).any() and times[-1] <= t_next
        t_end = times[-1] if arrive else t_next
        ts = np.arange(t, t_end, dense_step_s)
        flown += [state_on(times, legs, x)[0] for x in ts]
        flown_t += list(ts)
        if arrive:
            flown.append(legs[-1])
            flown_t.append(times[-1])
            run.arrived_s = float(times[-1])
            break
        ne, course = state_on(times, legs, t_next)
        t = t_next
        planner.plan_ = None  # the thesis replans at every nowcast update
    run.flown_ne, run.flown_t = np.array(flown), np.array(flown_t)
    return run
