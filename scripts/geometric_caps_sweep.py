"""Recalibrate the geometric avoider's time/energy normalisation caps with the thesis sweep.

Runs the Table 4.1 sweep (16 200 environments, spec §7.1; ``sim.testbeds.geometric_sweep``) for a
vehicle, keeps the raw cost terms of every collision-free candidate and prints:
- the caps (G20): lower = min, upper = 99.5 % value, time upper × 1.15 — paste them into
  ``CostCaps`` defaults when the vehicle or the discretisation changes;
- the reference-environment values (#1440 lower, #11088 upper) as a cross-check;
- the distribution checks of spec §7.6 (ln S_rp range, corr(E_n, T_n), hover-power spread).

    python scripts/geometric_caps_sweep.py [--stride 1] [--workers 2] [--set v_cruise=15 ...]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from avoidance.geometric.config import VehicleParams  # noqa: E402
from avoidance.geometric.normalization import caps_from_samples, clip_minmax  # noqa: E402
from sim.testbeds.geometric_sweep import LOWER_CAP_ENV, N_ENVIRONMENTS, UPPER_CAP_ENV, run_sweep, sweep_config  # noqa: E402

THESIS_CAPS = {"time_lo": 1.2530, "time_hi": 8.1436, "energy_lo": 249.59, "energy_hi": 1759.0}


def _chunk(args: tuple[list[int], VehicleParams]) -> dict[str, np.ndarray]:
    envs, veh = args
    return run_sweep(envs, sweep_config(), veh)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--stride", type=int, default=1, help="use every n-th environment")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE", help="VehicleParams override")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "geometric_caps.json")
    args = ap.parse_args()
    veh = replace(VehicleParams(), **{k: float(v) for k, v in (s.split("=", 1) for s in args.set)})
    envs = list(range(0, N_ENVIRONMENTS, args.stride))
    chunks = [envs[i :: args.workers * 8] for i in range(args.workers * 8)]
    t0 = time.perf_counter()
    with ProcessPoolExecutor(args.workers) as ex:
        parts = list(ex.map(_chunk, [(c, veh) for c in chunks]))
    data = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    wall = time.perf_counter() - t0
    caps = caps_from_samples(data["time"], data["energy"])
    ref = {
        name: run_sweep([e], sweep_config(), veh) for name, e in (("lower", LOWER_CAP_ENV), ("upper", UPPER_CAP_ENV))
    }
    t_n = clip_minmax(data["time"], caps.time_lo, caps.time_hi)
    e_n = clip_minmax(data["energy"], caps.energy_lo, caps.energy_hi)
    cv = lambda a: float(np.std(a) / np.mean(a))  # noqa: E731
    ln_srp = np.log(data["smoothness_rp"])
    m = data["cmo"][data["cmo"] > 0]
    report = {
        "vehicle": asdict(veh),
        "config": {
            k: getattr(sweep_config(), k)
            for k in ("l", "n_planes", "path_types", "x_step_fraction", "dynamic_mode", "uav_shape")
        },
        "environments": len(envs),
        "samples": int(data["time"].size),
        "wall_s": wall,
        "caps": asdict(caps),
        "thesis_caps": THESIS_CAPS,
        "caps_vs_thesis_pct": {k: 100.0 * (getattr(caps, k) / v - 1.0) for k, v in THESIS_CAPS.items()},
        "time_p995_s": float(np.quantile(data["time"], 0.995)),
        "time_max_s": float(data["time"].max()),
        "energy_max_j": float(data["energy"].max()),
        "reference_env_1440": {
            "time_min": float(ref["lower"]["time"].min()),
            "energy_min": float(ref["lower"]["energy"].min()),
        },
        "reference_env_11088": {
            "time_max": float(ref["upper"]["time"].max()),
            "energy_max": float(ref["upper"]["energy"].max()),
        },
        "ln_smoothness_rp_range": [float(ln_srp.min()), float(ln_srp.max())],
        "ln_smoothness_rp_inside_pct": float(100.0 * np.mean((ln_srp >= -3) & (ln_srp <= 3))),
        "ln_cmo_range": [float(np.log(m).min()), float(np.log(m).max())],
        "corr_energy_time_normalised": float(np.corrcoef(e_n, t_n)[0, 1]),
        "cv_hover_power": cv(data["hover_power"]),
        "cv_time": cv(data["time"]),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=2))
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
