"""The planner core: generation → kinematics → collision check → costs → selection
(spec §1.3, §5.9). Frame-free of the harness: local ENU z-up [m, m/s], τ [s] from the evading
instant (the UAV at ``start`` on the reference line, flying along ``x_dir``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from avoidance.geometric.collision import candidate_clearance, segseg_distance
from avoidance.geometric.config import GeometricConfig, VehicleParams
from avoidance.geometric.conflict import MainThreat
from avoidance.geometric.costs import closeness, energy, hover_power, rotation_penalty, sample_threat_paths, smoothness
from avoidance.geometric.frames import unit
from avoidance.geometric.generation import CandidateSet, generate_candidates
from avoidance.geometric.kinematics import Kinematics, path_kinematics
from avoidance.geometric.normalization import clip_minmax, log_clip_minmax
from avoidance.geometric.threats import ThreatArrays


class Status(str, Enum):
    AVOID = "avoid"  # a collision-free candidate was chosen
    TOO_CLOSE = "too_close"  # evading point closer than min_sep_factor·R to the main threat
    NO_SOLUTION = "no_solution"  # no candidate is collision-free (or all exceed max_cost)


RAW_TERMS = ("time", "energy", "smoothness", "smoothness_rp", "cmo", "hover_power")


@dataclass(slots=True)
class CostTable:
    """Per-candidate cost terms (K,), NaN for unavailable candidates. ``raw``: time [s], energy
    [J], smoothness and S_rp [1/m], CMO [1/m], hover power sum [W]; ``normalised`` in [0, 1];
    ``total`` the weighted sum (eq. 4.35)."""

    raw: dict[str, np.ndarray]
    normalised: dict[str, np.ndarray]
    total: np.ndarray


@dataclass(slots=True)
class AvoidanceResult:
    """Outcome of one planning call. ``clearance`` (K, J) [m] and ``available`` (K,) come from the
    collision check, ``chosen`` indexes the candidates, ``timings`` are wall seconds per stage."""

    status: Status
    main: MainThreat
    candidates: CandidateSet | None = None
    kinematics: Kinematics | None = None
    clearance: np.ndarray | None = None
    available: np.ndarray | None = None
    costs: CostTable | None = None
    chosen: int | None = None
    t_max: float = float("nan")
    timings: dict[str, float] = field(default_factory=dict)

    @property
    def cost(self) -> float:
        if self.chosen is None or self.costs is None:
            return float("nan")
        return float(self.costs.total[self.chosen])


def sweep_durations(
    threats: ThreatArrays, main_index: int | None, main_t_cpa: float, t_max: float, cfg: GeometricConfig
) -> np.ndarray:
    """(J,) collision-path durations [s]: t_max, except a moving main threat, which runs to the
    collision point (``main_t_cpa`` [s] ahead) plus ``main_threat_extension_s`` (G12, G13)."""
    d = np.full(len(threats), t_max)
    if main_index is not None and not threats.static[main_index]:
        d[main_index] = max(main_t_cpa, 0.0) + cfg.main_threat_extension_s
    return d


def cmo_threats(start: np.ndarray, threats: ThreatArrays, durations: np.ndarray, cfg: GeometricConfig) -> np.ndarray:
    """Indices of the moving threats entering the CMO term: within ``cmo_max_range_m`` of the
    evading point (distance to the collision path), the ``cmo_max_objects`` nearest."""
    moving = np.flatnonzero(~threats.static)
    if moving.size == 0:
        return moving
    a, b, _ = threats.collision_paths(durations)
    d = segseg_distance(start, start, a[moving], b[moving])
    keep = moving[d <= cfg.cmo_max_range_m]
    return keep[np.argsort(d[d <= cfg.cmo_max_range_m], kind="stable")[: cfg.cmo_max_objects]]


def evaluate_costs(
    c: CandidateSet,
    kin: Kinematics,
    idx: np.ndarray,
    threats: ThreatArrays,
    durations: np.ndarray,
    cfg: GeometricConfig,
    veh: VehicleParams,
) -> CostTable:
    """Cost terms of the candidates ``idx`` (the available ones), scattered into (K,) arrays."""
    pts, n = c.points[idx], c.n_pts[idx]
    s_shape = np.concatenate([smoothness(x, y, cfg.smoothness) for x, y in c.shapes])
    s = s_shape[c.shape_index[idx]]
    cm = cmo_threats(c.start, threats, durations, cfg)
    a, b, radius = threats.collision_paths(durations)
    samples = sample_threat_paths(a[cm], b[cm], cfg.x_step_fraction * c.dx, cfg.cmo_threat_samples)
    raw_sub = {
        "time": kin.T[idx],
        "energy": energy(pts, kin.wp_vel[idx], veh, cfg.rho, cfg.g),
        "smoothness": s,
        "smoothness_rp": rotation_penalty(s, c.alpha[idx], cfg.k_p),
        "cmo": closeness(pts, n, samples, radius[cm], cfg),
        "hover_power": hover_power(kin.seg_vel[idx], n, veh, cfg.rho, cfg.g, cfg.hover_literal_ki),
    }
    caps, (_, lim_rp, lim_m) = cfg.caps, cfg.log_limits
    norm_sub = {
        "time": clip_minmax(raw_sub["time"], caps.time_lo, caps.time_hi),
        "energy": clip_minmax(raw_sub["energy"], caps.energy_lo, caps.energy_hi),
        "smoothness_rp": log_clip_minmax(raw_sub["smoothness_rp"], *lim_rp),
        "cmo": log_clip_minmax(raw_sub["cmo"], *lim_m),
    }
    k_s, k_t, k_c = cfg.weights
    total_sub = k_s * norm_sub["smoothness_rp"] + k_t * norm_sub["time"] + k_c * norm_sub["cmo"]

    def scatter(v: np.ndarray) -> np.ndarray:
        out = np.full(len(c), np.nan)
        out[idx] = v
        return out

    return CostTable(
        {k: scatter(v) for k, v in raw_sub.items()}, {k: scatter(v) for k, v in norm_sub.items()}, scatter(total_sub)
    )


def select(costs: CostTable, available: np.ndarray, max_cost: float | None) -> int | None:
    """Cheapest available candidate; ties by lower normalised time, then index (spec §5.9)."""
    idx = np.flatnonzero(available)
    if idx.size == 0:
        return None
    best = int(idx[np.lexsort((idx, costs.normalised["time"][idx], costs.total[idx]))[0]])
    return None if max_cost is not None and costs.total[best] > max_cost else best


def plan_avoidance(
    start: np.ndarray,
    x_dir: np.ndarray,
    ref_speed: float,
    threats: ThreatArrays,
    main: MainThreat,
    cfg: GeometricConfig,
    veh: VehicleParams,
) -> AvoidanceResult:
    """Plan around ``main`` (a threat of ``threats``, every one of which is checked) from the
    evading point ``start`` [m] on a reference along ``x_dir`` flown at ``ref_speed`` [m/s]."""
    clock = time.perf_counter
    t0 = clock()
    x_hat = unit(x_dir)
    dx = float((main.p_c - start) @ x_hat)
    if dx < cfg.min_sep_factor * main.radius:
        return AvoidanceResult(Status.TOO_CLOSE, main, timings={"generation": clock() - t0})
    cands = generate_candidates(start, x_hat, dx, main.radius, cfg)
    t1 = clock()
    kin = path_kinematics(cands.points, cands.n_pts, veh.v_cruise, veh.max_roc)
    t_max = float(kin.T.max())
    t2 = clock()
    durations = sweep_durations(threats, main.index, main.t_cpa, t_max, cfg)
    clearance = candidate_clearance(
        cands.points,
        kin.seg_vel,
        kin.tau,
        kin.seg_dt,
        threats,
        cfg.dynamic_mode,
        durations,
        x_hat * ref_speed,
        t_max + cfg.rejoin_check_s,
    )
    available = np.all(clearance >= cfg.r_uav + cfg.select_margin_m, axis=1)
    if cfg.min_height_m is not None:
        available &= cands.points[:, :, 2].min(axis=1) >= cfg.min_height_m
    t3 = clock()
    costs = evaluate_costs(cands, kin, np.flatnonzero(available), threats, durations, cfg, veh)
    t4 = clock()
    chosen = select(costs, available, cfg.max_cost)
    t5 = clock()
    return AvoidanceResult(
        Status.AVOID if chosen is not None else Status.NO_SOLUTION,
        main,
        cands,
        kin,
        clearance,
        available,
        costs,
        chosen,
        t_max,
        {"generation": t1 - t0, "kinematics": t2 - t1, "collision": t3 - t2, "cost": t4 - t3, "selection": t5 - t4},
    )


def path_clearance(
    points: np.ndarray,
    times: np.ndarray,
    threats: ThreatArrays,
    main_index: int | None,
    main_t_cpa: float,
    tail_vel: np.ndarray,
    cfg: GeometricConfig,
) -> float:
    """Smallest clearance [m] (distance minus threat radius) of a path (N, 3) [m] flown on the
    schedule ``times`` (N,) [s, τ = 0 now, increasing] and then at ``tail_vel`` (3,) [m/s], with
    the rules used to choose a candidate (the path is clear if it is >= r_uav); inf without
    threats."""
    pts = np.asarray(points, float)[None]
    dt = np.diff(np.asarray(times, float))[None]
    if np.any(dt <= 0):
        raise ValueError("path times must be strictly increasing")
    vel = np.diff(pts, axis=1) / dt[..., None]
    tau = np.concatenate([[0.0], np.cumsum(dt[0])])[None]
    durations = sweep_durations(threats, main_index, main_t_cpa, float(tau[0, -1]), cfg)
    clearance = candidate_clearance(
        pts, vel, tau, dt, threats, cfg.dynamic_mode, durations, tail_vel, float(tau[0, -1]) + cfg.rejoin_check_s
    )
    return float(clearance.min(initial=np.inf))
