"""The MPTP behind the shared planner interface (sim.core.plan.Planner).

Frames/units: the estimate and the plan in local-level NED [m], storms in (north, east) [m],
times in sim seconds [s]. The planner keeps its last plan and replans at a fixed cadence
(``replan_period_s``), at the first call, whenever the mission's goal waypoint changes and
whenever a new nowcast arrives (the thesis replans at every nowcast update); in between it
returns the same plan. A replan keeps flying the current plan (the same object, so the follower
keeps its place on it) while that plan reaches the goal, is flown on schedule and stays clear of
the new nowcast, unless the new plan arrives earlier by more than ``keep_slack`` of the remaining
time (keeping.py). A replan (Algorithm 2 of seed 002):

1. the storm nowcast (``threats.storms``) becomes an ObstacleTimeline (cached per nowcast and
   probability level);
2. if the goal stays covered over the whole horizon: a holding orbit (status DEGRADED), at the
   nearest pre-defined holding location the search reaches with a free orbit, else here;
3. else the time-dependent A* from the estimated state (position, course; predicted
   ``start_lead_s`` ahead, lead_in.py, the prediction being the plan's first leg) to the goal, with
   one-way auxiliary states while the goal is covered at the direct arrival time (5.4);
   a plan that circles (holding) is DEGRADED;
4. if the search fails (expansion cap, or exhausted): the partial trajectory to the expanded
   state with the best heuristic that lasts until the next replan (DEGRADED; every leg is
   conflict free like any other), else straight flight inside the estimated safe area
   (NO_SOLUTION).

Navigation first: the first plan waits while the estimate's horizontal position sigma (the
larger of its N and E 1-sigma, ``VehicleState.pos_sigma_m``) is above ``nav_std_max_m``, at most
one ``replan_period_s`` from the first call: it flies straight on, a DEGRADED plan (diagnostics
``reason`` and ``nav_sigma_m`` [m], ``levels_tried`` 0), and the next call replans. A plan made
on the EKF's initial alignment would put its first turn where the first GNSS fix moves the
estimate by metres; only the first plan waits.

Steps 1-4 run for every probability level of the config, largest P first; the first plan that
reaches the goal is flown (3.1.1: "the feasible solution with the highest P"), and when no
level's does, the largest P's fall-back (the largest margins; a smaller P only earns its
smaller margins by reaching the goal). Diagnostics ``probability`` and ``levels_tried``.

With a wind forecast (wind.py) every step runs in the air-mass frame of the wind at the flight
level (the mean of the estimate's and the goal's heights): storms drift at their velocity minus
the wind, the goal drifts at minus the wind, the course is that of the air velocity, and the
planned states map back to the ground at their times.

Each replan plans at the vehicle's current true airspeed (the mean of the estimate's over the
last ``replan_period_s``, sampled at every call and, between calls, at ``observe_hz`` (1 Hz,
sim.core.plan.ObservingPlanner), so that a few noisy pitot samples do not set a plan's schedule
(the first plan, one call after the first, would otherwise rest on two), samples taken while a
plan commands airspeeds left out; the configured
``tas_mps`` while the estimate has none, while the plan in force commands airspeeds (a hold at
V_cor: the estimate is then V_cor, not the cruise speed V the hold was planned from), or always
with ``speed_source = "config"``), so the turn radius and leg lengths follow the speed as it
grows with altitude at a fixed equivalent airspeed; and only with the storm cells whose vertical
extent the vehicle can be near over the horizon (vertical.py).

A holding orbit flown at V_cor (``hold_speed_correction``, holding.py) is commanded through the
plan's ``airspeeds``: V_cor on the orbit's legs, V on the legs to a pre-defined holding location
(and on a lead-in, the speed of the leg it leads into); every other plan commands none, so the
follower flies its cruise airspeed again after a hold. Such a hold is planned at the configured
V = ``tas_mps`` (the cruise speed), never at the estimate's: a commanded speed must not carry
the airspeed estimate's noise (sigma ~0.6 m/s at 18 km on the EKF, about the 2.6 % of the
correction itself) or, while holding, V_cor taken for V.

The plan's vertices are the trajectory states, with the modelled turns written out between them
for the fly-over turn models (turnmodel.written_out); labels are -1 except the goal (its waypoint
index). In a plan that reaches the goal the altitude goes linearly (constant climb angle) from
the estimate's to the goal's; in one that does not (partial, holding, safe-area flight) it goes
from the estimate's towards the goal's at ``climb_rate_mps`` over the plan's time, within the
height band the plan's cells were chosen for (vertical.py), so a partial plan does not stall a
climb or a descent.
"""

from __future__ import annotations

import math
import time
from collections import deque

import numpy as np
import shapely
from shapely.geometry import Polygon

from guidance.mptp.config import MptpConfig
from guidance.mptp.goal import GoalTrack
from guidance.mptp.heuristics import GoalAvailability
from guidance.mptp.holding import corrected_speed_mps, holding_orbit, safe_area_leg
from guidance.mptp.keeping import TOUCH_M, extra_growth_m, position_at, remaining_clear
from guidance.mptp.lead_in import LeadIn, held_turn_rate, lead_in
from guidance.mptp.search import HOLD, Trajectory, default_workspace, plan_trajectory
from guidance.mptp.statespace import free_space
from guidance.mptp.timeline import ObstacleTimeline
from guidance.mptp.turnmodel import vertex_spacing_m, written_out
from guidance.mptp.vertical import altitude_band, cells_in_band, height_towards
from guidance.mptp.wind import WindForecast, air_goal, to_air, to_ground
from sim.core.mission import Mission
from sim.core.plan import Plan, PlanStatus, Threats
from sim.core.state import VehicleState
from sim.core.threats import StormSnapshot

MIN_AIRSPEED = 1.0  # below this the course is taken from the yaw [m/s]

Hold = tuple[np.ndarray, np.ndarray, np.ndarray | None, str]  # points, times, airspeeds, reason


class MptpPlanner:
    """Weather-avoiding planner for a fixed-wing aircraft flying ``mission``.

    ``goal_track``: a predicted track of a moving goal (replaces the mission waypoint as the
    target of the current leg; default ``config.goal_track``); ``config``: aircraft, search and
    margin parameters; ``wind``: the wind forecast the planner may know (None = still air)."""

    name = "mptp"
    observe_hz = 1.0  # the estimate's airspeed (and, with wind_forecast "estimate", wind) sampled between calls [Hz]

    def __init__(
        self,
        mission: Mission,
        config: MptpConfig | None = None,
        goal_track: GoalTrack | None = None,
        wind: WindForecast | None = None,
    ):
        self.mission = mission
        self.wind = wind
        self.wind_ne = np.zeros(2)  # wind of the last replan's air-mass frame (north, east) [m/s]
        self.cfg = config or MptpConfig()
        if self.cfg.turn_model != "simple" and mission.acceptance_radius >= vertex_spacing_m(self.cfg):
            raise ValueError(
                f"mptp: acceptance_radius {mission.acceptance_radius:g} m must be below the "
                f"{vertex_spacing_m(self.cfg):.1f} m between the written-out turn vertices of turn_model "
                f"{self.cfg.turn_model!r}"
            )
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
        self._timelines: dict[float, ObstacleTimeline] = {}  # of the last nowcast, per P
        self._issue: tuple = ()  # identity of the last nowcast seen
        self._tas: deque[tuple[float, float]] = deque()  # (t [s], TAS [m/s]) sampled over the last period
        self._air_wind: deque[tuple[float, float, float]] = deque()  # (t [s], north, east [m/s]), idem
        self._t_sampled: float | None = None  # time of the last samples [s]
        self._t_first: float | None = None  # time of the first replan [s]
        self._planned = False  # a plan other than a navigation wait was made
        self._nav_wait = False  # the plan in force waits for the navigation

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
        issue = tuple((id(s), s.t) for s in threats.storms)
        due = k != self._goal_index or issue != self._issue or t - self._t_plan >= self.cfg.replan_period_s - 1e-9
        due = due or self._nav_wait
        self._issue = issue
        self.observe(estimate, t)
        if self.plan_ is None or due:
            self.plan_ = self._replan(estimate, threats.storms or [StormSnapshot(t, ())], t, k)
            self._t_plan, self._goal_index = t, k
        return self.plan_

    def _keeps(self, est: VehicleState, new: Plan, t: float, k: int, now: MptpConfig, near, key) -> bool:
        """Whether to fly on the current plan instead of ``new`` (keeping.py): it reaches goal
        ``k``, the aircraft is within ``keep_within_m`` of where it has it now, the rest of it is
        clear of this nowcast's obstacle at its probability and the extra margin it was planned
        with (keeping.extra_growth_m), and ``new`` does not arrive earlier
        by more than ``keep_slack`` of its remaining time."""
        old = self.plan_
        if old is None or self.cfg.keep_within_m <= 0 or k != self._goal_index or old.times[-1] <= t:
            return False
        if not (old.labels >= 0).any():
            return False
        if np.linalg.norm(np.asarray(est.pos_ned[:2], float) - position_at(old, t)) > self.cfg.keep_within_m:
            return False
        if (new.labels >= 0).any() and new.times[-1] - t < (1.0 - self.cfg.keep_slack) * (old.times[-1] - t):
            return False
        p = float(old.diagnostics.get("probability", now.probability))
        cfg = now if p == now.probability else now.with_(probability=p)
        tl, _ = self._timeline_for(near, t, self.wind_ne, cfg, key)
        return remaining_clear(old, tl, t, self.wind_ne, TOUCH_M + extra_growth_m(old, tl, cfg))

    def margins_at(self, t: float):
        """The margin region of the last replan's timeline at time ``t`` [s], on the ground
        (north, east) [m] (None before the first replan)."""
        if self.timeline is None:
            return None
        shift = to_ground(np.zeros(2), t, self.wind_ne, self.timeline.t_issue)
        return shapely.affinity.translate(self.timeline.shape_at(t), *shift)

    def _timeline_for(
        self, storms: list[StormSnapshot], t: float, wind: np.ndarray, cfg: MptpConfig, key: tuple
    ) -> tuple[ObstacleTimeline, float]:
        """The timeline of ``storms`` at ``cfg``'s probability, cached per P while ``key`` (the
        nowcast and the cells that apply), the wind and the planning speed stay the same."""
        key = (*key, tuple(wind), cfg.tas_mps)
        if key != self._nowcast_key:
            self._timelines, self._nowcast_key = {}, key
        if cfg.probability not in self._timelines:
            wall = time.perf_counter()
            self._timelines[cfg.probability] = ObstacleTimeline(storms, cfg, t + 2 * cfg.horizon_s, wind)
            return self._timelines[cfg.probability], time.perf_counter() - wall
        return self._timelines[cfg.probability], 0.0

    def observe(self, estimate: VehicleState, t: float) -> None:
        """Samples the estimate's airspeed and wind at ``t`` [s] (each time once: a call at an
        observation's time adds nothing)."""
        if self._t_sampled == t:
            return
        self._t_sampled = t
        self._sample_tas(estimate, t)
        self._sample_wind(estimate, t)

    def _sample_tas(self, est: VehicleState, t: float) -> None:
        """Adds the estimate's TAS at ``t`` [s] and drops the samples older than one
        ``replan_period_s``; an estimate below ``MIN_AIRSPEED`` (none), or one taken while the
        plan in force commands airspeeds (a hold at V_cor), clears them."""
        if est.tas_mps < MIN_AIRSPEED or (self.plan_ is not None and self.plan_.airspeeds is not None):
            self._tas.clear()
            return
        self._tas.append((t, float(est.tas_mps)))
        self._drop_old(self._tas, t)

    def _sample_wind(self, est: VehicleState, t: float) -> None:
        """With ``wind_forecast = "estimate"``: adds the wind the estimate implies at
        ``t`` [s] (ground velocity minus the horizontal air velocity, the TAS along the estimated
        heading with the vertical speed taken out) and drops the samples older than one
        ``replan_period_s``; none below ``MIN_AIRSPEED``."""
        if self.cfg.wind_forecast != "estimate" or est.tas_mps < MIN_AIRSPEED:
            return
        v = est.vel_ned
        air = math.sqrt(max(float(est.tas_mps) ** 2 - float(v[2]) ** 2, 0.0))
        yaw = float(est.euler[2])
        self._air_wind.append((t, float(v[0]) - air * math.cos(yaw), float(v[1]) - air * math.sin(yaw)))
        self._drop_old(self._air_wind, t)

    def _drop_old(self, samples: deque, t: float) -> None:
        """Drops the (t [s], ...) samples older than one ``replan_period_s`` before ``t``."""
        while samples[0][0] <= t - self.cfg.replan_period_s:
            samples.popleft()

    def config_now(self, est: VehicleState) -> MptpConfig:
        """The configuration at the vehicle's current true airspeed [m/s] (``speed_source``
        "estimate": the mean of the estimate's sampled over the last ``replan_period_s``,
        this one's alone when none was; the configured one while the estimate's is below
        ``MIN_AIRSPEED`` or the plan in force commands airspeeds)."""
        holds = self.plan_ is not None and self.plan_.airspeeds is not None
        if self.cfg.speed_source == "config" or est.tas_mps < MIN_AIRSPEED or holds:
            return self.cfg
        tas = np.mean([v for _, v in self._tas]) if self._tas else est.tas_mps
        return self.cfg.with_(tas_mps=float(tas))

    def _storms_near(self, est: VehicleState, storms: list[StormSnapshot], k: int, cfg: MptpConfig):
        """The cells the vehicle can come near in height over the horizon (vertical.py), the
        cache key of that selection, and the number of cells left out of the first snapshot."""
        up_goal = -float(self.mission.waypoints[k, 2])
        band = altitude_band(-float(est.pos_ned[2]), up_goal, cfg.climb_rate_mps, cfg.horizon_s)
        near, dropped = cells_in_band(storms, band, cfg.vertical_margin_m)
        return near, (*((id(s), s.t) for s in storms), dropped), len(dropped[0]) if dropped else 0

    def _wind_at(self, est: VehicleState, k: int, t: float) -> np.ndarray:
        """The wind (north, east) [m/s] a plan from ``est`` to waypoint ``k`` at time ``t`` [s]
        takes as steady: the forecast at the mean of the two heights, at ``t``; with
        ``wind_forecast = "estimate"`` the mean of the sampled estimate winds."""
        if self.cfg.wind_forecast == "estimate":
            return np.mean([w[1:] for w in self._air_wind], axis=0) if self._air_wind else np.zeros(2)
        if self.wind is None:
            return np.zeros(2)
        return self.wind.at(-0.5 * (float(est.pos_ned[2]) + float(self.mission.waypoints[k, 2])), t)

    def _replan(self, est: VehicleState, storms: list[StormSnapshot], t: float, k: int) -> Plan:
        """Plans for every probability level, largest P first, and keeps the first feasible
        plan (one that reaches the goal); when none is, the largest P's fall-back (3.1.1). Every
        level plans at the current airspeed with the cells the vehicle can come near in height."""
        self.wind_ne = self._wind_at(est, k, t)
        now = self.config_now(est)
        near, key, ignored = self._storms_near(est, storms, k, now)
        levels = self.cfg.probability_levels
        if self._waits_for_navigation(est, t):
            top = now if levels[0] == now.probability else now.with_(probability=levels[0])
            plan = self._navigation_wait(top, est, near, key, t)
            plan.diagnostics.update(probability=levels[0], levels_tried=0, cells_ignored=ignored)
            return plan
        self._planned = True
        fallback: tuple[Plan, ObstacleTimeline, Trajectory | None] | None = None
        chosen: tuple[Plan, ObstacleTimeline, Trajectory | None] | None = None
        for p in levels:
            cfg = now if p == now.probability else now.with_(probability=p)
            plan, traj = self._replan_at(cfg, est, near, key, t, k)
            plan.diagnostics.update(probability=p, levels_tried=levels.index(p) + 1, cells_ignored=ignored)
            assert self.timeline is not None
            if traj is not None and traj.status == "ok":
                chosen = (plan, self.timeline, traj)
                break
            fallback = fallback or (plan, self.timeline, traj)
        if chosen is None:
            assert fallback is not None
            chosen = fallback
            chosen[0].diagnostics["levels_tried"] = len(levels)
        if self.plan_ is not None and self._keeps(est, chosen[0], t, k, now, near, key):
            self.timeline = chosen[1]
            return self.plan_
        plan, self.timeline, self.trajectory = chosen
        return plan

    def _waits_for_navigation(self, est: VehicleState, t: float) -> bool:
        """Whether the replan at ``t`` [s] waits for the navigation: no plan was made yet, the
        estimate's horizontal position sigma is above ``nav_std_max_m`` and the first replan was
        less than one ``replan_period_s`` ago."""
        if self._t_first is None:
            self._t_first = t
        waiting = t - self._t_first < self.cfg.replan_period_s - 1e-9
        self._nav_wait = not self._planned and waiting and nav_sigma_m(est) > self.cfg.nav_std_max_m
        return self._nav_wait

    def _navigation_wait(
        self, cfg: MptpConfig, est: VehicleState, storms: list[StormSnapshot], key: tuple, t: float
    ) -> Plan:
        """The plan that waits for the navigation: straight on the current air course for one
        ``replan_period_s`` at ``cfg``'s speed (DEGRADED), with the timeline of ``cfg``'s probability
        built (the next replan reuses it) and the diagnostics of a replan."""
        wall = time.perf_counter()
        tl, weather_s = self._timeline_for(storms, t, self.wind_ne, cfg, key)
        self.timeline = tl
        p0, course = self._air_start(est, t, tl.t_issue)
        lead = lead_in(p0, t, course, 0.0, cfg.tas_mps, 0.0)
        end = p0 + cfg.tas_mps * cfg.replan_period_s * np.array([math.cos(course), math.sin(course)])
        sigma = nav_sigma_m(est)
        diag = self._diagnostics(cfg, weather_s)
        diag.update(
            reason=f"navigation: position sigma {sigma:.1f} m > nav_std_max_m {cfg.nav_std_max_m:g} m",
            nav_sigma_m=sigma,
            runtime_s=time.perf_counter() - wall,
        )
        pts, times = np.vstack([p0, end]), t + np.r_[0.0, cfg.replan_period_s]
        return self._to_plan(t, est, lead, pts, times, np.full(2, -1), PlanStatus.DEGRADED, diag)

    def _air_start(self, est: VehicleState, t: float, t_ref: float) -> tuple[np.ndarray, float]:
        """The estimate's position (2,) [m] in the air-mass frame of the last wind (reference
        time ``t_ref`` [s]) and its air course [rad] (the yaw below MIN_AIRSPEED)."""
        w = self.wind_ne
        v_air = np.asarray(est.vel_ned[:2], float) - w
        course = math.atan2(v_air[1], v_air[0]) if np.hypot(*v_air) >= MIN_AIRSPEED else est.yaw
        return to_air(np.asarray(est.pos_ned[:2], float), t, w, t_ref), course

    def _diagnostics(self, cfg: MptpConfig, weather_s: float) -> dict[str, float | int | str]:
        """The diagnostics every replan's plan carries."""
        w = self.wind_ne
        diag: dict[str, float | int | str] = {
            "heuristic": cfg.heuristic,
            "weather_s": weather_s,
            "tas_mps": cfg.tas_mps,
            "start_lead_s": cfg.start_lead_s,
        }
        if w.any():
            diag.update(wind_north_mps=float(w[0]), wind_east_mps=float(w[1]))
        return diag

    def _replan_at(
        self, cfg: MptpConfig, est: VehicleState, storms: list[StormSnapshot], key: tuple, t: float, k: int
    ) -> tuple[Plan, Trajectory | None]:
        """One replan at ``cfg``'s probability and speed on ``storms`` (``key``: their cache key):
        the plan and the search's trajectory (None when the goal is covered over the whole
        horizon and the plan holds)."""
        w = self.wind_ne
        tl, weather_s = self._timeline_for(storms, t, w, cfg, key)
        self.timeline = tl
        t_ref = tl.t_issue
        ground_goal = self.goal_track or GoalTrack.fixed(self.mission.waypoints[k, :2])
        goal = air_goal(ground_goal, w, t_ref, t, t + 2 * cfg.horizon_s) if w.any() else ground_goal
        p_now, course_now = self._air_start(est, t, t_ref)
        rate = held_turn_rate(est.roll, cfg.tas_mps, cfg.g)
        lead = lead_in(p_now, t, course_now, rate, cfg.tas_mps, cfg.start_lead_s)
        p0, t0, course = lead.p, lead.t, lead.course
        diag = self._diagnostics(cfg, weather_s)
        wall = time.perf_counter()
        workspace = self._workspace(p0, goal, t, w, t_ref, cfg)
        availability = GoalAvailability(tl, goal)
        levels = tl.interval(t + np.arange(0.0, cfg.horizon_s + cfg.dt_s, cfg.dt_s))
        if all(availability.covered(int(j)) for j in levels):
            hcfg = cfg.with_(tas_mps=self.cfg.tas_mps) if cfg.hold_speed_correction else cfg
            hold = self._hold_at_point(hcfg, tl, p0, t0, course) or self._hold_here(hcfg, tl, p0, t0, course)
            if hold is not None:
                pts, times, speeds, reason = hold
                diag.update(runtime_s=time.perf_counter() - wall, holding_s=float(times[-1] - t), reason=reason)
                if speeds is not None:
                    diag["hold_tas_mps"] = float(speeds[-1])
                labels = np.full(len(pts), -1)
                plan = self._to_plan(t, est, lead, pts, times, labels, PlanStatus.DEGRADED, diag, airspeeds=speeds)
                return plan, None
        arrival = float(goal.intercept(p0, np.array([t0]), cfg.tas_mps)[0])
        turning = _one_way(cfg.turning) if availability.covered(int(tl.interval(arrival))) else cfg.turning
        # a partial trajectory must last until the next replan (the follower flies straight on
        # past a plan's end)
        traj = plan_trajectory(
            tl,
            p0,
            t0,
            course,
            goal,
            cfg,
            workspace,
            turning=turning,
            min_partial_s=cfg.replan_period_s + t - t0,
            bank0=est.roll,
        )
        diag.update(
            expanded=traj.expanded,
            trst=max(len(traj.positions) - 1, 0),
            runtime_s=traj.runtime_s,
            turning=turning,
            search=traj.status,
        )
        if traj.start_space is not None:
            diag["vertices"] = len(traj.start_space.boundary.verts)
        if traj.note:
            diag["search_note"] = traj.note
        pts, times, rates = traj.positions, traj.times, None
        if cfg.turn_model != "simple" and len(pts) >= 2:
            pts, times, rates = written_out(pts, times, traj.courses, traj.kinds[1:] == HOLD, cfg, traj.start_bank)
        if traj.status == "ok":
            holding = traj.holding_turn >= 2 * math.pi - 1e-6
            labels = np.full(len(pts), -1)
            labels[-1] = k
            diag.update(eta_s=float(traj.times[-1] - t), holding_turns=traj.holding_turn / (2 * math.pi))
            status = PlanStatus.DEGRADED if holding else PlanStatus.OK
            return self._to_plan(t, est, lead, pts, times, labels, status, diag, rates), traj
        if len(pts) >= 2:  # the search's best progress towards the goal
            diag.update(reason="search " + traj.status + ": partial plan", eta_s=float(traj.times[-1] - t))
            plan = self._to_plan(t, est, lead, pts, times, np.full(len(pts), -1), PlanStatus.DEGRADED, diag, rates)
            return plan, traj
        fs = traj.start_space or free_space(tl, p0, t0, workspace, cfg.tas_mps, cfg.ring_segments)
        end, _ = safe_area_leg(fs, course, cfg, cfg.tas_mps * cfg.replan_period_s * 2)
        pts = np.vstack([p0, end])
        times = t0 + np.r_[0.0, np.linalg.norm(end - p0) / cfg.tas_mps]
        diag["reason"] = "search " + traj.status
        return self._to_plan(t, est, lead, pts, times, np.full(2, -1), PlanStatus.NO_SOLUTION, diag), traj

    def _hold_here(self, cfg: MptpConfig, tl: ObstacleTimeline, p0: np.ndarray, t: float, course: float) -> Hold | None:
        """A holding orbit from the current state until the next replan, or None."""
        orbit = holding_orbit(tl, p0, t, course, t + cfg.replan_period_s, cfg, _one_way(cfg.turning))
        return None if orbit is None else (orbit[0], orbit[1], _hold_airspeeds(cfg, 0, len(orbit[0])), "goal covered")

    def _hold_at_point(
        self, cfg: MptpConfig, tl: ObstacleTimeline, p0: np.ndarray, t: float, course: float
    ) -> Hold | None:
        """The trajectory to the nearest pre-defined holding location (5.4) that the search
        reaches and whose orbit, for a replan period after arrival, is free; None when none is.
        With the speed correction the legs to it are commanded at V and the orbit's at V_cor."""
        points = np.asarray(cfg.holding_points, float).reshape(-1, 2)
        w, t_ref = self.wind_ne, tl.t_issue
        ground = to_air(points, t, w, t_ref) if w.any() else points
        for i in np.argsort(np.linalg.norm(ground - p0, axis=1), kind="stable"):
            fix = GoalTrack.fixed(points[i])
            goal = air_goal(fix, w, t_ref, t, t + 2 * cfg.horizon_s) if w.any() else fix
            traj = plan_trajectory(tl, p0, t, course, goal, cfg, self._workspace(p0, goal, t, w, t_ref, cfg))
            if traj.status != "ok":
                continue
            t_arr = float(traj.times[-1])
            orbit = holding_orbit(
                tl,
                traj.positions[-1],
                t_arr,
                float(traj.courses[-1]),
                t_arr + cfg.replan_period_s,
                cfg,
                _one_way(cfg.turning),
            )
            if orbit is not None:
                pts = np.vstack([traj.positions, orbit[0][1:]])
                speeds = _hold_airspeeds(cfg, len(traj.positions) - 1, len(pts))
                times = np.concatenate([traj.times, orbit[1][1:]])
                return pts, times, speeds, f"goal covered: holding at point {int(i)}"
        return None

    def _workspace(
        self, p0: np.ndarray, goal: GoalTrack, t: float, w: np.ndarray, t_ref: float, cfg: MptpConfig
    ) -> Polygon:
        """The search's workspace in the air-mass frame: the start and the goal over the horizon,
        padded; the mission area is swept by -w over the horizon (a convex superset)."""
        area = cfg.mission_area
        if area is not None and w.any():
            ends = [to_air(np.zeros(2), x, w, t_ref) for x in (t, t + cfg.horizon_s)]
            area = shapely.convex_hull(shapely.union_all([shapely.affinity.translate(area, *e) for e in ends]))
        return default_workspace(np.vstack([p0, goal.at(t), goal.at(t + cfg.horizon_s)]), cfg, area)

    def _to_plan(
        self,
        t: float,
        est: VehicleState,
        lead: LeadIn,
        ne: np.ndarray,
        times: np.ndarray,
        labels: np.ndarray,
        status: PlanStatus,
        diag: dict,
        turn_rates: np.ndarray | None = None,
        airspeeds: np.ndarray | None = None,
    ) -> Plan:
        """A plan from states (air-mass frame ``ne`` (N, 2) [m] at ``times`` [s], from the
        predicted start of ``lead``, which puts its lead-in leg in front) on the ground;
        ``turn_rates`` (N,) [rad/s]: the model's course rate on each leg (None: straight legs);
        ``airspeeds`` (N,) [m/s]: the commanded true airspeed on each leg (None: cruise), the
        lead-in flown at its first leg's."""
        n = len(ne)
        ne, times, labels, turn_rates = lead.prepend(ne, times, labels, turn_rates)
        if airspeeds is not None:
            airspeeds = np.r_[np.full(len(ne) - n, airspeeds[0]), airspeeds]
        ne = to_ground(ne, times, self.wind_ne, self.timeline.t_issue if self.timeline else t)
        d0 = float(est.pos_ned[2])
        d1 = float(self.mission.waypoints[self._goal_index_for(labels), 2])
        seg = np.linalg.norm(np.diff(ne, axis=0), axis=1)
        if (labels >= 0).any():
            diag["path_length_m"] = float(seg.sum())
        frac = np.concatenate([[0.0], np.cumsum(seg)]) / max(seg.sum(), 1e-9)
        if (labels >= 0).any():
            down = d0 + (d1 - d0) * frac
        else:
            elapsed = np.clip(np.asarray(times, float) - t, 0.0, self.cfg.horizon_s)
            down = -height_towards(-d0, -d1, self.cfg.climb_rate_mps, elapsed)
        pos = np.column_stack([ne, down])
        vel = np.diff(pos, axis=0) / np.maximum(np.diff(times), 1e-9)[:, None]
        vel = np.vstack([vel, vel[-1:]]) if len(vel) else np.zeros((1, 3))
        return Plan(
            t,
            pos,
            np.asarray(times, float),
            np.asarray(labels),
            status,
            vel,
            self.name,
            diag,
            turn_rates=turn_rates,
            airspeeds=airspeeds,
        )

    def _goal_index_for(self, labels: np.ndarray) -> int:
        return int(labels.max()) if (labels >= 0).any() else self.mission.next_index


def nav_sigma_m(est: VehicleState) -> float:
    """The estimate's horizontal position sigma [m]: the larger of its N and E 1-sigma (0 when
    it has none: truth, perfect sensors)."""
    return 0.0 if est.pos_sigma_m is None else float(np.max(np.asarray(est.pos_sigma_m, float)[:2]))


def _hold_airspeeds(cfg: MptpConfig, transit_legs: int, n: int) -> np.ndarray | None:
    """Commanded true airspeeds [m/s] of a hold plan's ``n`` vertices: V (``cfg.tas_mps``) on its
    first ``transit_legs`` legs (to a holding location), V_cor on the orbit's after them; None
    without the speed correction (the n-gon is flown at the cruise speed)."""
    if not cfg.hold_speed_correction:
        return None
    speeds = np.full(n, corrected_speed_mps(cfg))
    speeds[:transit_legs] = cfg.tas_mps
    return speeds


def _one_way(turning: str) -> str:
    return "right" if turning == "both" else turning
