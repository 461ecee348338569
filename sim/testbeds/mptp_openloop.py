"""Open-loop replanning runs as in the thesis's chapter 6 (no aircraft model).

Frames/units: (north, east) [m], times [s]. The MPTP is called every ``replan_period_s`` with a
fresh nowcast of the storm field; the aircraft is assumed to reach the commanded states in due
time (6.1), so the next initial state is the state on the current plan one period later. The
flown trajectory is the composite of the first period of every plan. Closed-loop flight with
JSBSim uses the same MptpPlanner through the runner.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from guidance.mptp.goal import GoalTrack
from guidance.mptp.planner import MptpPlanner
from sim.core.mission import Mission
from sim.core.plan import Plan, PlanStatus, Threats
from sim.core.state import VehicleState
from sim.testbeds.mptp_thesis import Scenario


@dataclass
class OpenLoopRun:
    plans: list[Plan] = field(default_factory=list)
    flown_ne: np.ndarray = field(default_factory=lambda: np.empty((0, 2)))  # (M, 2) [m]
    flown_t: np.ndarray = field(default_factory=lambda: np.empty(0))  # (M,) [s]
    arrived_s: float = float("nan")

    @property
    def length_m(self) -> float:
        return float(np.linalg.norm(np.diff(self.flown_ne, axis=0), axis=1).sum())


def state_on(plan: Plan, t: float) -> tuple[np.ndarray, float]:
    """Position (north, east) [m] and course [rad] at time t on the plan's legs."""
    times, ne = plan.times, plan.positions[:, :2]
    if len(times) == 1:
        return ne[0].copy(), 0.0
    k = int(np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 2))
    s = np.clip((t - times[k]) / max(times[k + 1] - times[k], 1e-9), 0.0, 1.0)
    d = ne[k + 1] - ne[k]
    return ne[k] + s * d, float(np.arctan2(d[1], d[0]))


def vehicle_state(t: float, ne: np.ndarray, course: float, speed: float) -> VehicleState:
    vel = speed * np.array([np.cos(course), np.sin(course), 0.0])
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
    sc: Scenario, reactive_goal: bool = False, iterations: int | None = None, dense_step_s: float = 10.0
) -> OpenLoopRun:
    """Replan ``iterations`` times (default: the scenario's) or until the goal is reached."""
    cfg = sc.cfg
    g0 = sc.goal.at(0.0)
    mission = Mission(np.array([[g0[0], g0[1], 0.0]]), cfg.tas_mps, acceptance_radius=cfg.leg_m)
    planner = MptpPlanner(mission, cfg, None if reactive_goal or not sc.goal.moving else sc.goal)
    run = OpenLoopRun()
    ne, course, t = sc.start.astype(float), sc.course, 0.0
    flown, flown_t = [], []
    for _ in range(iterations or sc.iterations):
        if reactive_goal:
            planner.goal_track = GoalTrack.fixed(sc.goal.at(t))
        threats = Threats(storms=sc.storms.nowcast(t, cfg.horizon_s))
        plan = planner.plan(vehicle_state(t, ne, course, cfg.tas_mps), threats, t)
        run.plans.append(plan)
        t_next = t + cfg.replan_period_s
        arrive = plan.status != PlanStatus.NO_SOLUTION and (plan.labels >= 0).any() and plan.times[-1] <= t_next
        t_end = plan.times[-1] if arrive else t_next
        ts = np.arange(t, t_end, dense_step_s)
        flown += [state_on(plan, x)[0] for x in ts]
        flown_t += list(ts)
        if arrive:
            flown.append(plan.positions[-1, :2])
            flown_t.append(plan.times[-1])
            run.arrived_s = float(plan.times[-1])
            break
        ne, course = state_on(plan, t_next)
        t = t_next
        planner.plan_ = None  # the thesis replans at every nowcast update
    run.flown_ne, run.flown_t = np.array(flown), np.array(flown_t)
    return run
