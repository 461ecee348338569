"""Geometric avoider: full-plan time for 16 candidates and N = 1 / 2 / 3 threats.

Reported against the thesis desktop means (Table 5.1: 0.0837 / 0.1527 / 0.2319 s, Xeon E5-1620 v3,
Python 3.7) and, measured in this same run, against ``baseline_plan``: a straightforward
thesis-style implementation looping over paths, segments and threats (scalar maths, SciPy KDTree
for closeness), which also serves the tests as a loop reference. Target: >= 20x faster than the
thesis.

Environments (spec §7.3): N = 1 one static threat; N = 2 plus one moving; N = 3 plus two moving,
drawn from the Table 4.1 sweep geometry (``sim.testbeds.geometric_sweep``); l = 4, n = 3, symmetric
paths (L = 16), thesis collision rules (swept) and the default time-synchronised check.

    python benchmarks/bench_geometric.py [--envs 60] [--repeat 5]

BLAS runs single-threaded (one plan is a handful of tiny matrix products; threads only add
contention). The JSON records the machine and its load average, since both move the numbers.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
from scipy.spatial import KDTree

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from avoidance.geometric.avoider import Status  # noqa: E402
from avoidance.geometric.config import PATH_TYPES, GeometricConfig, VehicleParams  # noqa: E402
from avoidance.geometric.conflict import main_threat  # noqa: E402
from avoidance.geometric.frames import plane_angles, plane_elevation, uav_frame  # noqa: E402
from avoidance.geometric.generation import omega_grid, shape_abscissae  # noqa: E402
from avoidance.geometric.threats import Threat, ThreatArrays  # noqa: E402
from sim.testbeds.geometric_encounters import Encounter  # noqa: E402
from sim.testbeds.geometric_sweep import N_ENVIRONMENTS, sweep_encounter  # noqa: E402

THESIS_MEAN_S = {1: 0.0837, 2: 0.1527, 3: 0.2319}


# ---- loop baseline -------------------------------------------------------------------------------
def _seg_dist(p1, q1, p2, q2) -> float:
    """Scalar Ericson segment-segment distance (§5.1.9)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e, f = float(d1 @ d1), float(d2 @ d2), float(d2 @ r)
    if a == 0.0 and e == 0.0:
        s = t = 0.0
    elif a == 0.0:
        s, t = 0.0, min(max(f / e, 0.0), 1.0)
    else:
        c = float(d1 @ r)
        if e == 0.0:
            s, t = min(max(-c / a, 0.0), 1.0), 0.0
        else:
            b = float(d1 @ d2)
            den = a * e - b * b
            s = min(max((b * f - c * e) / den, 0.0), 1.0) if den > 1e-12 * a * e else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                s, t = min(max(-c / a, 0.0), 1.0), 0.0
            elif t > 1.0:
                s, t = min(max((b - c) / a, 0.0), 1.0), 1.0
    return float(np.linalg.norm(p1 + d1 * s - (p2 + d2 * t)))


def _timed_dist(p, v, tau0, dt, th: Threat) -> float:
    """Scalar minimum of |UAV − threat| over one segment's time interval."""
    r0 = p - th.at(tau0)
    w = v - th.v
    ww = float(w @ w)
    s = min(max(-float(r0 @ w) / ww, 0.0), dt) if ww > 0 else 0.0
    return float(np.linalg.norm(r0 + w * s))


def baseline_collides(pts, vel, tau, threats, durations, mode, r_uav, tail_vel, horizon) -> bool:
    """One path (its real waypoints) against every threat, loop over threats and segments."""
    for j, th in enumerate(threats):
        if mode == "swept":
            a, b = th.p, th.p + th.v * durations[j]
            grown = th.radius + th.growth * durations[j]
            for i in range(len(pts) - 1):
                if _seg_dist(pts[i], pts[i + 1], a, b) - grown < r_uav:
                    return True
        else:
            segs = [(pts[i], vel[i], tau[i], tau[i + 1] - tau[i]) for i in range(len(pts) - 1)]
            segs.append((pts[-1], tail_vel, tau[-1], max(horizon - tau[-1], 0.0)))
            for p, v, t0, dt in segs:
                if _timed_dist(p, v, t0, dt, th) - (th.radius + th.growth * (t0 + dt)) < r_uav:
                    return True
    return False


def baseline_plan(enc: Encounter, cfg: GeometricConfig, veh: VehicleParams) -> tuple[int | None, dict[int, float]]:
    """Thesis-style plan: (chosen index or None, {available index: total cost}); candidate order
    as in ``generation``. Too close -> (None, {})."""
    x_hat = enc.x_dir / np.linalg.norm(enc.x_dir)
    ta = ThreatArrays.of(enc.threats)
    main = main_threat(enc.main_index, enc.start, x_hat * enc.speed, ta, cfg.conflict_horizon_s)
    dx = float((main.p_c - enc.start) @ x_hat)
    if dx < cfg.min_sep_factor * main.radius:
        return None, {}
    frame = uav_frame(x_hat)
    paths = []  # (kind, theta, alpha, shape x, shape y, pts, vel, tau)
    for kind in (PATH_TYPES.index(t) for t in cfg.path_types):
        for theta in plane_angles(cfg.n_planes):
            alpha = float(plane_elevation(frame, np.array([theta]))[0])
            for w in omega_grid(main.radius, cfg.l, cfg.omega_factor):
                xs = shape_abscissae(dx, kind, cfg.x_step_fraction)
                ys, pts = [], []
                for x in xs:
                    u = min(x, 2 * dx - x) / dx if kind == PATH_TYPES.index("symmetric") else x / dx
                    y = w * (3 * u * u - 2 * u**3)
                    ys.append(y)
                    pts.append(enc.start + frame @ np.array([x, y * math.cos(theta), y * math.sin(theta)]))
                vel, tau = [], [0.0]
                for i in range(len(pts) - 1):
                    d = pts[i + 1] - pts[i]
                    v = veh.v_cruise * d / np.linalg.norm(d)
                    if abs(v[2]) > veh.max_roc:
                        v = v * veh.max_roc / abs(v[2])
                    vel.append(v)
                    tau.append(tau[-1] + np.linalg.norm(d) / np.linalg.norm(v))
                paths.append((kind, theta, alpha, xs, np.array(ys), pts, vel, tau))
    t_max = max(p[7][-1] for p in paths)
    durations = [t_max] * len(enc.threats)
    if not enc.threats[enc.main_index].is_static:
        durations[enc.main_index] = main.t_cpa + cfg.main_threat_extension_s
    moving = [j for j, th in enumerate(enc.threats) if not th.is_static]
    dist0 = {j: _seg_dist(enc.start, enc.start, enc.threats[j].p, enc.threats[j].at(durations[j])) for j in moving}
    cmo_ids = sorted((j for j in moving if dist0[j] <= cfg.cmo_max_range_m), key=lambda j: dist0[j])[
        : cfg.cmo_max_objects
    ]
    trees = {}
    for j in cmo_ids:
        th = enc.threats[j]
        end = th.p + th.v * durations[j]
        n = max(cfg.cmo_threat_samples, int(np.ceil(np.linalg.norm(end - th.p) / (cfg.x_step_fraction * dx))) + 1)
        trees[j] = KDTree([th.p + (end - th.p) * u for u in np.linspace(0, 1, n)])
    (_, lim_rp, lim_m), caps, (k_s, k_t, k_c) = cfg.log_limits, cfg.caps, cfg.weights
    costs, t_norm = {}, {}
    for k, (_kind, _theta, alpha, xs, ys, pts, vel, tau) in enumerate(paths):
        if baseline_collides(
            pts,
            vel,
            tau,
            enc.threats,
            durations,
            cfg.dynamic_mode,
            cfg.r_uav,
            x_hat * enc.speed,
            t_max + cfg.rejoin_check_s,
        ):
            continue
        x1, y1 = np.gradient(xs), np.gradient(ys)
        x2, y2 = np.gradient(x1), np.gradient(y1)
        kappa = np.abs(x2 * y1 - x1 * y2) / (x1**2 + y1**2) ** 1.5
        s_rp = float(np.trapezoid(kappa**2, xs)) * (1 + cfg.k_p * abs(math.sin(alpha)))
        fs = []
        for j in cmo_ids:
            d = [max(trees[j].query(p)[0] - enc.threats[j].radius, cfg.cmo_min_distance) for p in pts]
            fs.append(1.0 / (cfg.k1 * float(np.mean(d)) + cfg.k2 * min(d)))
        m = 0.5 * max(fs) + 0.5 * float(np.mean(fs)) if fs else 0.0
        tn = (min(max(tau[-1], caps.time_lo), caps.time_hi) - caps.time_lo) / (caps.time_hi - caps.time_lo)
        log_n = lambda v, lo, hi: (min(max(math.log(v), lo), hi) - lo) / (hi - lo) if v > 0 else 0.0  # noqa: E731
        costs[k] = k_s * log_n(s_rp, *lim_rp) + k_t * tn + k_c * log_n(m, *lim_m)
        t_norm[k] = tn
    if not costs:
        return None, {}
    chosen = min(costs, key=lambda k: (costs[k], t_norm[k], k))
    return chosen, costs


# ---- environments and timing ---------------------------------------------------------------------
def environments(n_threats: int, count: int, seed: int = 7) -> list[Encounter]:
    """``count`` sweep environments that are not too close, with the main threat and
    ``n_threats - 1`` moving threats (the second one mirrored in elevation and direction)."""
    rng = np.random.default_rng(seed + n_threats)
    out = []
    for e in rng.permutation(N_ENVIRONMENTS):
        enc = sweep_encounter(int(e))
        main, moving = enc.threats
        if np.linalg.norm(main.p) < 2.5 * main.radius:
            continue
        mirror = Threat("moving2", moving.p * np.array([1, 1, -1]) + np.array([1.0, 0, 0]), -moving.v, moving.radius)
        out.append(Encounter(enc.start, enc.x_dir, (main, moving, mirror)[:n_threats]))
        if len(out) == count:
            return out
    return out


def _cpu_model() -> str:
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
        return next(ln.split(":", 1)[1].strip() for ln in lines if ln.startswith("model name"))
    except (OSError, StopIteration):
        return platform.processor() or platform.machine()


def median_time(fn, encs, repeat: int) -> float:
    times = []
    for enc in encs:
        for _ in range(repeat):
            t0 = time.perf_counter()
            fn(enc)
            times.append(time.perf_counter() - t0)
    return float(np.median(times))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--envs", type=int, default=60)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--baseline-envs", type=int, default=20)
    args = ap.parse_args()
    veh = VehicleParams()
    rows = []
    for mode in ("swept", "timed"):
        cfg = GeometricConfig(l=4, n_planes=3, path_types=("symmetric",), dynamic_mode=mode, start_shift_s=0.0)
        for n in (1, 2, 3):
            encs = environments(n, args.envs)
            for enc in encs[:3]:  # warm-up and agreement check
                res, (b_chosen, _) = enc.plan(cfg, veh), baseline_plan(enc, cfg, veh)
                assert res.chosen == b_chosen, (res.chosen, b_chosen)
            vec = median_time(lambda e, cfg=cfg: e.plan(cfg, veh), encs, args.repeat)
            base = median_time(lambda e, cfg=cfg: baseline_plan(e, cfg, veh), encs[: args.baseline_envs], 1)
            ok = sum(e.plan(cfg, veh).status is Status.AVOID for e in encs)
            rows.append(
                {
                    "mode": mode,
                    "threats": n,
                    "paths": 16,
                    "envs": len(encs),
                    "with_solution": ok,
                    "median_s": vec,
                    "baseline_median_s": base,
                    "thesis_mean_s": THESIS_MEAN_S[n],
                    "speedup_vs_thesis": THESIS_MEAN_S[n] / vec,
                    "speedup_vs_baseline": base / vec,
                }
            )
    print(
        f"{'mode':6} {'N':>2} {'median ms':>10} {'baseline ms':>12} {'thesis ms':>10} "
        f"{'x thesis':>9} {'x baseline':>11}"
    )
    for r in rows:
        print(
            f"{r['mode']:6} {r['threats']:>2} {1e3 * r['median_s']:10.3f} {1e3 * r['baseline_median_s']:12.2f} "
            f"{1e3 * r['thesis_mean_s']:10.1f} {r['speedup_vs_thesis']:9.1f} {r['speedup_vs_baseline']:11.1f}"
        )
    out = ROOT / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    info = {
        "cpu": _cpu_model(),
        "python": sys.version.split()[0],
        "numpy": np.__version__,
        "cpus": os.cpu_count(),
        "load_avg_1m": os.getloadavg()[0],
        "blas": (np.show_config(mode="dicts") or {}).get("Build Dependencies", {}).get("blas", {}).get("name", "?"),
    }
    (out / "bench_geometric.json").write_text(json.dumps({"machine": info, "rows": rows}, indent=2))
    print(f"machine: {info}; written {out / 'bench_geometric.json'}")


if __name__ == "__main__":
    main()
