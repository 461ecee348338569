"""The MPTP behind the shared planner interface (sim.core.plan.Planner).

Frames/units: the estimate and the plan in local-level NED [m], storms in (north, east) [m],
times in sim seconds [s]. The planner keeps its last plan and replans at a fixed cadence
(``replan_period_s``), at the first call and whenever the mission's goal waypoint changes; in
between it returns the same plan. A replan (Algorithm 2 of seed 002):

1. the storm nowcast (``threats.storms``) becomes an ObstacleTimeline (cached per nowcast);
2. if the goal stays covered over the whole horizon: a holding orbit (status DEGRADED);
3. else the time-dependent A* from the estimated state (position, course) to the goal, with
   one-way auxiliary states while the goal is covered at the direct arrival time (5.4);
   a plan that circles (holding) is DEGRADED;
4. if the search fails (expansion cap, or exhausted): the partial trajectory to the expanded
   state with the best heuristic that lasts until the next replan (DEGRADED; every leg is
   conflict free like any other), else straight flight inside the estimated safe area
   (NO_SOLUTION).

The plan's vertices are the trajectory states; labels are -1 except the goal (its waypoint
index); the altitude goes linearly (constant climb angle) from the estimate's to the goal's.
"""

from __future__ import annotations

import math
import time

import numpy as np

from guidance.mptp.config import MptpConfig
from guidance.mptp.goal import GoalTrack
from guidance.mptp.heuristics import GoalAvailability
from guidance.mptp.holding import holding_orbit, safe_area_leg
from guidance.mptp.search import Trajectory, default_workspace, plan_trajectory
from guidance.mptp.statespace import free_space
from guidance.mptp.timeline import ObstacleTimeline
from sim.core.mission import Mission
from sim.core.plan import Plan, PlanStatus, Threats
from sim.core.state import VehicleState
from sim.core.threats import StormSnapshot

MIN_GROUND_SPEED = 1.0  # below this the course is taken from the yaw [m/s]


class MptpPlanner:
    """Weather-avoiding planner for a fixed-wing aircraft flying ``mission``.

    ``goal_track``: a predicted track of a moving goal (replaces the mission waypoint as the
    target of the current leg; default ``config.goal_track``); ``config``: aircraft, search and
    margin parameters."""

    name = "mptp"

    def __init__(self, mission: Mission, config: MptpConfig | None = None, goal_track: GoalTrack | None = None):
        self.mission = mission
        self.cfg = config or MptpConfig()
        if goal_track is None and self.cfg.goal_track is not None:
            rows = np.array(self.cfg.goal_track)
            goal_track = GoalTrack(rows[:, 0], rows[:, 1:])
        self.goal_track = goal_track
        self.plan_: Plan | None = None
        self.trajectory: Trajectory | None = None
        self.timeline: ObstacleTimeline | None = None
        self._t_plan = -math.inf
        self._goal_index = -1
        self._nowcast_key: tuple | None = None

    def plan(self, estimate: VehicleState, threats: Threats, t: float) -> Plan:
        m = self.mission
        if m.waypoints_done:
            last = m.waypoints[-1:]
            return Plan(
                t,
                last.copy(),
                np.array([t]),
                np.array([len(m.waypoints) - 1]),
                PlanStatus.OK,
                planner=self.name,
                diagnostics={"complete": 1},
            )
        k = m.next_index
        if self.plan_ is None or k != self._goal_index or t - self._t_plan >= self.cfg.replan_period_s - 1e-9:
            self.plan_ = self._replan(estimate, threats.storms or [StormSnapshot(t, ())], t, k)
            self._t_plan, self._goal_index = t, k
        return self.plan_

    def _timeline_for(self, storms: list[StormSnapshot], t: float) -> tuple[ObstacleTimeline, float]:
        key = tuple((id(s), s.t) for s in storms)
        if key != self._nowcast_key or self.timeline is None:
            wall = time.perf_counter()
            self.timeline = ObstacleTimeline(storms, self.cfg, t + 2 * self.cfg.horizon_s)
            self._nowcast_key = key
            return self.timeline, time.perf_counter() - wall
        return self.timeline, 0.0

    def _replan(self, est: VehicleState, storms: list[StormSnapshot], t: float, k: int) -> Plan:
        cfg = self.cfg
        tl, weather_s = self._timeline_for(storms, t)
        goal = self.goal_track or GoalTrack.fixed(self.mission.waypoints[k, :2])
        p0 = np.asarray(est.pos_ned[:2], float)
        course = est.course_rad if est.ground_speed_mps >= MIN_GROUND_SPEED else est.yaw
        diag: dict[str, float | int | str] = {"heuristic": cfg.heuristic, "weather_s": weather_s}
        wall = time.perf_counter()
        availability = GoalAvailability(tl, goal)
        levels = tl.interval(t + np.arange(0.0, cfg.horizon_s + cfg.dt_s, cfg.dt_s))
        if all(availability.covered(int(j)) for j in levels):
            orbit = holding_orbit(tl, p0, t, course, t + cfg.replan_period_s, cfg, _one_way(cfg.turning))
            if orbit is not None:
                pts, times, _ = orbit
                diag.update(runtime_s=time.perf_counter() - wall, holding_s=float(times[-1] - t), reason="goal covered")
                return self._to_plan(t, est, pts, times, np.full(len(pts), -1), PlanStatus.DEGRADED, diag)
        arrival = t + float(np.linalg.norm(goal.at(t) - p0)) / cfg.tas_mps
        turning = _one_way(cfg.turning) if availability.covered(int(tl.interval(arrival))) else cfg.turning
        # a partial trajectory must last until the next replan (the follower flies straight on
        # past a plan's end)
        traj = plan_trajectory(tl, p0, t, course, goal, cfg, turning=turning, min_partial_s=cfg.replan_period_s)
        self.trajectory = traj
        diag.update(
            expanded=traj.expanded,
            trst=max(len(traj.positions) - 1, 0),
            runtime_s=traj.runtime_s,
            turning=turning,
            search=traj.status,
        )
        if traj.start_space is not None:
            diag["vertices"] = len(traj.start_space.boundary.verts)
        if traj.status == "ok":
            holding = traj.holding_turn >= 2 * math.pi - 1e-6
            labels = np.full(len(traj.positions), -1)
            labels[-1] = k
            diag.update(
                path_length_m=traj.length_m,
                eta_s=float(traj.times[-1] - t),
                holding_turns=traj.holding_turn / (2 * math.pi),
            )
            status = PlanStatus.DEGRADED if holding else PlanStatus.OK
            return self._to_plan(t, est, traj.positions, traj.times, labels, status, diag)
        if len(traj.positions) >= 2:  # the search's best progress towards the goal
            diag.update(reason="search " + traj.status + ": partial plan", eta_s=float(traj.times[-1] - t))
            return self._to_plan(
                t, est, traj.positions, traj.times, np.full(len(traj.positions), -1), PlanStatus.DEGRADED, diag
            )
        fs = traj.start_space or free_space(
            tl, p0, t, default_workspace(p0, goal.at(t), cfg), cfg.tas_mps, cfg.ring_segments
        )
        end, _ = safe_area_leg(fs, course, cfg, cfg.tas_mps * cfg.replan_period_s * 2)
        pts = np.vstack([p0, end])
        times = t + np.r_[0.0, np.linalg.norm(end - p0) / cfg.tas_mps]
        diag["reason"] = "search " + traj.status
        return self._to_plan(t, est, pts, times, np.full(2, -1), PlanStatus.NO_SOLUTION, diag)

    def _to_plan(
        self,
        t: float,
        est: VehicleState,
        ne: np.ndarray,
        times: np.ndarray,
        labels: np.ndarray,
        status: PlanStatus,
        diag: dict,
    ) -> Plan:
        d0 = float(est.pos_ned[2])
        d1 = float(self.mission.waypoints[self._goal_index_for(labels), 2])
        seg = np.linalg.norm(np.diff(ne, axis=0), axis=1)
        frac = np.concatenate([[0.0], np.cumsum(seg)]) / max(seg.sum(), 1e-9)
        down = d0 + (d1 - d0) * frac if (labels >= 0).any() else np.full(len(ne), d0)
        pos = np.column_stack([ne, down])
        vel = np.diff(pos, axis=0) / np.maximum(np.diff(times), 1e-9)[:, None]
        vel = np.vstack([vel, vel[-1:]]) if len(vel) else np.zeros((1, 3))
        return Plan(t, pos, np.asarray(times, float), np.asarray(labels), status, vel, self.name, diag)

    def _goal_index_for(self, labels: np.ndarray) -> int:
        return int(labels.max()) if (labels >= 0).any() else self.mission.next_index


def _one_way(turning: str) -> str:
    return "right" if turning == "both" else turning
