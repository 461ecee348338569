"""``GeometricAvoider``: the geometric candidate-path avoider (seed 001) behind the shared
planner protocol ``sim.core.plan.Planner``.

Boundary: estimates, threats and plans are local NED [m, m/s], sim time [s]; the core works in
local ENU z-up and τ from the evading instant (converted here and in ``reference``).

Per call: until the vehicle has passed the committed avoidance path's rejoin point (judged by
its along-track position, not the clock: the follower may lag the schedule) the path is
re-checked (``still_valid``, re-timed from the vehicle's progress) and kept if still clear;
otherwise the conflict monitor (CPA along the reference) looks for a main threat. No conflict ->
the reference. Conflict -> candidates around it from the evading point (the vehicle's
along-track position moved ahead by its along-track speed × ``start_shift_s``), the chosen path
then the rest of the reference. No collision-free candidate (or too close) -> NO_SOLUTION with
a hover plan at the current position, unless flying on along the reference is predicted to stay
clearer of the threats than holding (then the reference plan, ``response = fly_on``).
Candidates are generated at most once per ``min_replan_interval_s``; a conflict inside that
interval (including a committed path found unsafe) gets the same fallback (``status =
rate_limited``). A committed path found unsafe while the
vehicle is more than ``replan_max_offset_m`` off the reference is not dropped (the candidates
would start on the reference, out of reach): the vehicle hovers (``status = suspended``) and
resumes the path once its re-check is clear again, unless holding position is predicted to come
closer to a threat than flying on, then it flies on (``status = committed_unsafe``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from avoidance.geometric.avoider import AvoidanceResult, Status, path_clearance, plan_avoidance
from avoidance.geometric.config import PATH_TYPES, GeometricConfig, VehicleParams
from avoidance.geometric.conflict import MainThreat, cpa, detection_horizon, find_main_threat
from avoidance.geometric.generation import CandidateSet
from avoidance.geometric.kinematics import Kinematics
from avoidance.geometric.reference import ReferenceLine
from avoidance.geometric.threats import Threat, ThreatArrays, inflate
from sim.core.frames import enu_to_ned, ned_to_enu
from sim.core.plan import Plan, PlanStatus, Threats
from sim.core.state import VehicleState

_Diagnostics = dict[str, float | int | str | None]  # None values are left out of the plan's diagnostics


@dataclass(frozen=True, slots=True)
class _Commitment:
    """The avoidance path being flown: ENU points [m] from the plan's start to the rejoin point,
    their along-track distances on the reference [m] (increasing: every candidate advances along
    x̂), the absolute times they were scheduled for [s], the plan handed out, the main threat's id
    and the absolute time it reaches the collision point [s]."""

    points_enu: np.ndarray
    along: np.ndarray
    times: np.ndarray
    plan: Plan
    main_id: str
    t_cpa: float

    def passed(self, s_now: float, length: float) -> bool:
        """Whether along-track distance ``s_now`` [m] is past the rejoin point, or at the end of a
        reference of ``length`` [m] the path rejoins beyond (the projection stops there)."""
        return s_now >= min(float(self.along[-1]), length)

    def remaining(self, s_now: float) -> tuple[np.ndarray, np.ndarray]:
        """The rest of the path from along-track distance ``s_now`` [m] (its point there first) and
        its schedule re-timed to the vehicle's progress [s, τ = 0 now]: a vehicle behind (or
        ahead of) the schedule shifts every later time by its lag. A vehicle still short of the
        path's first point is taken as there."""
        s_now = max(s_now, float(self.along[0]))
        here = np.array([np.interp(s_now, self.along, self.points_enu[:, i]) for i in range(3)])
        later = self.along > s_now
        t_here = np.interp(s_now, self.along, self.times)
        return np.vstack([here, self.points_enu[later]]), np.concatenate([[0.0], self.times[later] - t_here])


def sensed_threats(threats: Threats, t0: float, k_sigma: float, own_m: float = 0.0) -> tuple[list[Threat], int]:
    """Spheres and intruder tracks as core threats predicted to time ``t0`` [s] (ENU, radius
    inflated by the covariances, §3.1, and by ``own_m`` [m], the allowance for the ownship's own
    position error), and the number of threat objects this planner ignores (obstacles,
    geofences, storms, LiDAR)."""
    out = []
    for th in threats.spheres:
        r, g = inflate(th.radius_m, th.center_cov, None, k_sigma, t0 - th.t)
        out.append(_predicted(th.id, th.center_ned, th.vel_ned, r + own_m, g, t0 - th.t))
    for tr in threats.intruders:
        r, g = inflate(tr.radius_m, tr.pos_cov, tr.vel_cov, k_sigma, t0 - tr.t)
        out.append(_predicted(tr.id, tr.pos_ned, tr.vel_ned, r + own_m, g, t0 - tr.t))
    ignored = len(threats.obstacles) + len(threats.geofences) + len(threats.storms) + (threats.lidar is not None)
    return out, ignored


def _predicted(tid: str, p_ned: np.ndarray, v_ned: np.ndarray, radius: float, growth: float, age: float) -> Threat:
    if not (np.isfinite(radius) and radius > 0):
        raise ValueError(f"threat {tid!r}: radius must be finite and > 0, got {radius!r}")
    v = ned_to_enu(v_ned)
    return Threat(tid, ned_to_enu(p_ned) + v * age, v, radius, growth)


def _json(v: object) -> object:
    """Plain-JSON value: arrays to lists, NaN/inf to None."""
    a = np.asarray(v)
    if a.dtype.kind == "f":
        out = a.astype(object)
        out[~np.isfinite(a)] = None
        return out.tolist()
    return a.tolist()


def _chosen(res: AvoidanceResult) -> tuple[CandidateSet, Kinematics, int]:
    """The candidates, their kinematics and the chosen index of an ``AVOID`` result."""
    if res.candidates is None or res.kinematics is None or res.chosen is None:
        raise ValueError(f"a {res.status.value!r} result has no chosen candidate")
    return res.candidates, res.kinematics, res.chosen


class GeometricAvoider:
    """Planner protocol implementation. ``reference_ned`` (M, 3) straight NED polyline and its
    ``speed`` [m/s] may be given here or later with :meth:`set_reference`."""

    name = "geometric"

    def __init__(
        self,
        reference_ned: np.ndarray | None = None,
        speed: float | None = None,
        config: GeometricConfig | None = None,
        vehicle: VehicleParams | None = None,
        first_label: int = 0,
    ):
        """``first_label``: the label of the reference's first vertex (plans label the reference
        vertices ``index + first_label``, -1 where that is negative): -1 when the reference is
        [start, mission waypoints...] so that the labels are the mission waypoint indices."""
        self.first_label = first_label
        self.config = config or GeometricConfig()
        self.vehicle = vehicle or VehicleParams()
        self.reference: ReferenceLine | None = None
        self._commit: _Commitment | None = None
        self._t_planned = -np.inf  # time of the last candidate generation [s]
        self._last: tuple[float, AvoidanceResult, list[Threat]] | None = None
        self._own_m = 0.0  # the last estimate's own-position allowance [m]
        if reference_ned is not None:
            if speed is None:
                raise ValueError("a reference needs its speed")
            self.set_reference(reference_ned, speed)

    def set_reference(self, reference_ned: np.ndarray, speed: float) -> None:
        """Replace the reference (straight NED polyline [m], speed [m/s]); drops any commitment."""
        self.reference = ReferenceLine.from_ned(reference_ned, speed)
        self._commit = None

    def reset(self) -> None:
        self._commit = None
        self._t_planned = -np.inf
        self._last = None
        self._own_m = 0.0

    def own_allowance(self, estimate: VehicleState) -> float:
        """``k_sigma_own`` x the largest 1-sigma axis of the estimate's position [m] (0 when it
        carries no uncertainty)."""
        sigma = estimate.pos_sigma_m
        if self.config.k_sigma_own == 0.0 or sigma is None:
            return 0.0
        return self.config.k_sigma_own * float(np.max(sigma))

    def horizons(self, start: np.ndarray, threats: ThreatArrays, to_end: float) -> np.ndarray:
        """(J,) conflict look-ahead [s] per threat from the evading point ``start`` (ENU [m]):
        ``conflict_horizon_s``, or longer where a conflict first seen at that horizon would
        already be too close for candidates (one ``min_replan_interval_s`` of lead; see
        :func:`~avoidance.geometric.conflict.detection_horizon`); at most ``to_end`` [s], the time
        to the reference end."""
        cfg, ref = self.config, self._require_reference()
        _, miss = cpa(start, ref.velocity, threats, to_end)
        closing = np.linalg.norm(threats.v - ref.velocity, axis=1)
        need = detection_horizon(
            miss,
            closing,
            threats,
            cfg.r_uav + cfg.select_margin_m,
            cfg.min_sep_factor,
            ref.speed,
            cfg.min_replan_interval_s,
        )
        return np.minimum(np.maximum(cfg.conflict_horizon_s, need), to_end)

    # -- protocol -------------------------------------------------------------------------------
    def plan(self, estimate: VehicleState, threats: Threats, t: float) -> Plan:
        t_start = time.perf_counter()
        ref = self._require_reference()
        pos, vel = ned_to_enu(estimate.pos_ned), ned_to_enu(estimate.vel_ned)
        if not (np.isfinite(t) and np.all(np.isfinite(pos)) and np.all(np.isfinite(vel))):
            raise ValueError("estimate position, velocity and time must be finite")
        cfg = self.config
        self._own_m = self.own_allowance(estimate)
        s_now, cross = ref.project(pos)
        replan = ""
        commit = self._commit
        if commit is not None and not commit.passed(s_now, ref.length):
            go, hold = self._commit_clearances(commit, threats, t, estimate.pos_ned)
            if go >= cfg.r_uav:
                return self._with_diagnostics(commit.plan, {"status": "committed"}, t_start)
            replan = "invalid"
            if cross > cfg.replan_max_offset_m:  # candidates start on the reference, out of reach
                diag: _Diagnostics = {"cross_track_m": cross, "clearance_go_m": go, "clearance_hold_m": hold}
                if hold >= go:
                    return self._with_diagnostics(
                        self._hover_plan(t, estimate.pos_ned), {**diag, "status": "suspended"}, t_start
                    )
                return self._with_diagnostics(commit.plan, {**diag, "status": "committed_unsafe"}, t_start)
        self._commit = None
        v_along = min(max(float(vel @ ref.x_hat), 0.0), ref.speed)
        s_e = min(s_now + v_along * cfg.start_shift_s, ref.length)
        t_e = t + cfg.start_shift_s
        core, ignored = sensed_threats(threats, t_e, cfg.k_sigma, self._own_m)
        base: _Diagnostics = {"cross_track_m": cross, "ignored_threats": ignored, "replan_reason": replan}
        start = ref.point(s_e)
        ta = ThreatArrays.of(core)
        to_end = (ref.length - s_e) / ref.speed
        horizons = self.horizons(start, ta, to_end)
        main = (
            find_main_threat(start, ref.velocity, ta, cfg.r_uav + cfg.select_margin_m, horizons, to_end)
            if to_end > 0
            else None
        )
        if main is None:
            return self._with_diagnostics(self._reference_plan(t, s_now), {**base, "status": "no_conflict"}, t_start)
        horizon = float(horizons[main.index])
        diag = {**base, "main_threat_id": core[main.index].id, "t_cpa_s": main.t_cpa, "horizon_s": horizon}
        if t - self._t_planned < cfg.min_replan_interval_s:
            fallback, extra = self._fallback_plan(t, estimate.pos_ned, s_now, start, ta, main, horizon)
            return self._with_diagnostics(fallback, {**diag, **extra, "status": "rate_limited"}, t_start)
        self._t_planned = t
        res = plan_avoidance(start, ref.x_hat, ref.speed, ta, main, cfg, self.vehicle)
        self._last = (t, res, core)
        diag |= {
            "status": res.status.value,
            "n_candidates": 0 if res.candidates is None else len(res.candidates),
            "n_available": 0 if res.available is None else int(res.available.sum()),
            **{f"t_{k}_s": v for k, v in res.timings.items()},
        }
        if res.status is not Status.AVOID:
            fallback, extra = self._fallback_plan(t, estimate.pos_ned, s_now, start, ta, main, horizon)
            return self._with_diagnostics(fallback, diag | extra, t_start)
        diag |= {"chosen_index": res.chosen, "cost": res.cost}
        cands, kin, k = _chosen(res)
        plan = self._avoid_plan(t, s_now, s_e, t_e, cands, kin, k)
        m = cands.n_pts[k] + (s_e > s_now)  # [lead point +] the chosen path
        pts = ned_to_enu(plan.positions[:m])
        self._commit = _Commitment(
            pts, (pts - ref.origin) @ ref.x_hat, plan.times[:m], plan, core[main.index].id, t_e + main.t_cpa
        )
        return self._with_diagnostics(plan, diag, t_start)

    def still_valid(self, threats: Threats, t: float, pos_ned: np.ndarray) -> bool:
        """Whether the rest of the committed avoidance path, from the along-track position of the
        vehicle at ``pos_ned`` (NED [m]) at time ``t`` [s] and re-timed to its progress, is still
        clear of the sensed threats with the rules used to choose it (the vehicle radius without
        ``select_margin_m``). False when nothing is committed or the rejoin point is passed."""
        c = self._commit
        ref = self._require_reference()
        if c is None or c.passed(ref.project(ned_to_enu(pos_ned))[0], ref.length):
            return False
        return self._commit_clearances(c, threats, t, pos_ned)[0] >= self.config.r_uav

    def _commit_clearances(
        self, c: _Commitment, threats: Threats, t: float, pos_ned: np.ndarray
    ) -> tuple[float, float]:
        """Smallest predicted clearances [m] to the sensed threats of (flying the rest of the
        committed path ``c`` re-timed to the vehicle's progress, holding position at ``pos_ned``
        (NED [m]) over the same time), from time ``t`` [s]."""
        ref, cfg = self._require_reference(), self.config
        here = ned_to_enu(pos_ned)
        pts, times = c.remaining(ref.project(here)[0])
        core, _ = sensed_threats(threats, t, cfg.k_sigma, self._own_m)
        ids = [th.id for th in core]
        main_index = ids.index(c.main_id) if c.main_id in ids else None
        ta = ThreatArrays.of(core)
        go = path_clearance(pts, times, ta, main_index, c.t_cpa - t, ref.velocity, cfg)
        hold = path_clearance(np.vstack([here, here]), times[[0, -1]], ta, main_index, c.t_cpa - t, np.zeros(3), cfg)
        return go, hold

    def candidate_log(self) -> dict[str, object] | None:
        """The last planning event's candidates as plain lists/dicts (NED points K×N×3, n_pts,
        ω [m], θ/α [deg], type, availability, raw and normalised cost terms, total, choice,
        stage timings [s]); None before any candidates were generated."""
        if self._last is None:
            return None
        t, res, core = self._last
        c, available, clearance, costs = res.candidates, res.available, res.clearance, res.costs
        if c is None or available is None or clearance is None or costs is None:
            return None
        return {
            "t": t,
            "status": res.status.value,
            "main_threat_id": core[res.main.index].id,
            "chosen": res.chosen,
            "t_max_s": res.t_max,
            "points_ned": _json(enu_to_ned(c.points)),
            "n_pts": _json(c.n_pts),
            "omega_m": _json(c.omega),
            "theta_deg": _json(np.degrees(c.theta)),
            "alpha_deg": _json(np.degrees(c.alpha)),
            "path_type": [PATH_TYPES[k] for k in c.kind],
            "available": _json(available),
            "min_clearance_m": _json(clearance.min(axis=1, initial=np.inf)),
            "raw": {k: _json(v) for k, v in costs.raw.items()},
            "normalised": {k: _json(v) for k, v in costs.normalised.items()},
            "cost": _json(costs.total),
            "timings_s": dict(res.timings),
        }

    # -- plans ----------------------------------------------------------------------------------
    def _labels(self, idx: np.ndarray) -> np.ndarray:
        lab = np.asarray(idx, int) + self.first_label
        return np.where(lab >= 0, lab, -1)

    def _require_reference(self) -> ReferenceLine:
        if self.reference is None:
            raise RuntimeError("GeometricAvoider has no reference; call set_reference() first")
        return self.reference

    def _reference_plan(self, t: float, s_now: float) -> Plan:
        ref = self._require_reference()
        pos, times, idx, vel = ref.onward(s_now, t)
        first_v = enu_to_ned(ref.velocity) if len(idx) else np.zeros(3)
        return Plan(
            t,
            np.vstack([enu_to_ned(ref.point(s_now)), pos]),
            np.concatenate([[t], times]),
            np.concatenate([[-1], self._labels(idx)]),
            PlanStatus.OK,
            np.vstack([first_v, vel]),
            self.name,
        )

    def _fallback_plan(
        self,
        t: float,
        pos_ned: np.ndarray,
        s_now: float,
        start: np.ndarray,
        ta: ThreatArrays,
        main: MainThreat,
        horizon: float,
    ) -> tuple[Plan, _Diagnostics]:
        """The plan when no candidate is flown (too close, no solution, rate limited): the hover
        plan at ``pos_ned`` (NED [m]), or the reference from along-track ``s_now`` [m] when flying
        on from the evading point ``start`` (ENU [m]) is predicted clearer of the threats ``ta``
        (predicted to the evading instant) than holding, both over the conflict ``horizon`` [s]
        and ``rejoin_check_s``; ties hover (the spec's no-solution response)."""
        ref, cfg = self._require_reference(), self.config
        here = ned_to_enu(pos_ned)
        span = np.array([0.0, horizon])
        go = path_clearance(
            np.vstack([start, start + ref.velocity * horizon]), span, ta, main.index, main.t_cpa, ref.velocity, cfg
        )
        hold = path_clearance(np.vstack([here, here]), span, ta, main.index, main.t_cpa, np.zeros(3), cfg)
        diag: _Diagnostics = {"clearance_go_m": go, "clearance_hold_m": hold}
        if go > hold:
            return self._reference_plan(t, s_now), {**diag, "response": "fly_on"}
        return self._hover_plan(t, pos_ned), {**diag, "response": "hover"}

    def _hover_plan(self, t: float, pos_ned: np.ndarray) -> Plan:
        return Plan(
            t,
            np.asarray(pos_ned, float)[None].copy(),
            np.array([t]),
            np.array([-1]),
            PlanStatus.NO_SOLUTION,
            np.zeros((1, 3)),
            self.name,
        )

    def _avoid_plan(
        self, t: float, s_now: float, s_e: float, t_e: float, cands: CandidateSet, kin: Kinematics, k: int
    ) -> Plan:
        """[along-track point now (if the start was moved ahead)] + candidate ``k`` + rest of the reference."""
        ref = self._require_reference()
        n = cands.n_pts[k]
        pts = cands.points[k, :n]
        vel = kin.wp_vel[k, :n]
        times = t_e + kin.tau[k, :n]
        s_end, _ = ref.project(pts[-1])
        tail_pos, tail_t, tail_idx, tail_vel = ref.onward(s_end, times[-1])
        lead = s_e > s_now
        pos = [enu_to_ned(ref.point(s_now))[None]] * lead + [enu_to_ned(pts), tail_pos]
        vels = [enu_to_ned(ref.velocity)[None]] * lead + [enu_to_ned(vel), tail_vel]
        return Plan(
            t,
            np.vstack(pos),
            np.concatenate([[t]] * lead + [times, tail_t]),
            np.concatenate([[-1]] * lead + [np.full(n, -1), self._labels(tail_idx)]),
            PlanStatus.OK,
            np.vstack(vels),
            self.name,
        )

    def _with_diagnostics(self, plan: Plan, diag: _Diagnostics, t_start: float) -> Plan:
        d: dict[str, float | int | str] = {k: v for k, v in diag.items() if v is not None}
        d["t_total_s"] = time.perf_counter() - t_start
        return Plan(plan.t, plan.positions, plan.times, plan.labels, plan.status, plan.velocities, plan.planner, d)
