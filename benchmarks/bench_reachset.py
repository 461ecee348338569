"""Benchmark of one avoidance grid run (threat collection + fusion + reachability + selection).

Scenes on the default thesis grid (350 cells, combined reach set, emergency mode = the four
category runs in priority order): 0, 1 and 5 intruders (line + body + time) and a dense LiDAR
scene (1° lattice, 7 walls). Reports the median wall time over ``--repeat`` runs on one core and
the ratio to the 0-intruder run measured in the same process; target ≤ 50 ms for 5 intruders.
Writes JSON to benchmarks/results/bench_reachset.json.

    python benchmarks/bench_reachset.py [--repeat 50]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from avoidance.reachset.cache import reach_set
from avoidance.reachset.config import AvoidanceConfig, MovementConfig
from avoidance.reachset.frames import GridPose
from avoidance.reachset.grid import AvoidanceGrid
from avoidance.reachset.gridrun import emergency_runs
from avoidance.reachset.movement import build_primitive_table
from avoidance.reachset.situation import Assessor
from sim.core.plan import Threats
from sim.core.threats import IntruderTrack, LidarScan


def intruders(n: int) -> list[IntruderTrack]:
    """Intruders converging on the grid from ahead and the sides (NED, grid heading north)."""
    out = []
    for k in range(n):
        ang = np.radians(-60.0 + 30.0 * k)
        pos = np.array([6.0 + 6.0 * np.cos(ang), 6.0 * np.sin(ang), 0.5 * (k - 2)])
        out.append(IntruderTrack(f"i{k}", 0.0, pos, -np.array([np.cos(ang), np.sin(ang), 0.0])))
    return out


def dense_scan() -> LidarScan:
    """1° × 1° rays over ±50° × ±35°; seven wall patches between 3 and 9 m."""
    az, el = np.meshgrid(
        np.radians(np.arange(-50.0, 50.5, 1.0)), np.radians(np.arange(-35.0, 35.5, 1.0)), indexing="ij"
    )
    dirs = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), -np.sin(el)], axis=-1).reshape(-1, 3)
    rng = np.full(len(dirs), 30.0)
    for north, east in [(3, -2.5), (4, 2), (5, 0), (6, -4), (7, 4.5), (8, 1), (9, -1)]:
        r = north / dirs[:, 0]
        p = dirs * r[:, None]
        hit = (np.abs(p[:, 1] - east) <= 0.8) & (np.abs(p[:, 2]) <= 2.0)
        rng = np.where(hit & (r < rng), r, rng)
    return LidarScan(0.0, np.zeros(3), dirs, rng, rng < 30.0, 30.0)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=50)
    args = ap.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    cfg = AvoidanceConfig()
    grid = AvoidanceGrid(cfg.grid)
    tree = reach_set(grid, build_primitive_table(MovementConfig()), cfg.avoidance)
    assessor = Assessor(grid, tree, cfg)
    pose = GridPose.from_ned(np.zeros(3), 0.0)
    goal = pose.ned_to_lcf(np.array([30.0, 0.0, 0.0]))
    scenes = {
        "0_intruders": Threats(),
        "1_intruder": Threats(intruders=intruders(1)),
        "5_intruders": Threats(intruders=intruders(5)),
        "dense_lidar": Threats(lidar=dense_scan()),
    }
    results = {}
    for name, threats in scenes.items():
        times, runs = [], 0
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            parts = assessor.assess(pose, 0.0, threats)
            made, sel = emergency_runs(grid, tree, parts, goal, cfg.fusion.threshold)
            times.append(time.perf_counter() - t0)
            runs = len(made)
        results[name] = {
            "median_ms": 1e3 * float(np.median(times)),
            "p90_ms": 1e3 * float(np.percentile(times, 90)),
            "category_runs": runs,
            "path_found": sel >= 0,
        }
    base = results["0_intruders"]["median_ms"]
    for r in results.values():
        r["ratio_to_0_intruders"] = r["median_ms"] / base
    report = {
        "benchmark": "reachset_grid_run",
        "nodes": tree.n_nodes,
        "cells": grid.n_cells,
        "repeat": args.repeat,
        "target_ms_5_intruders": 50.0,
        "meets_target": results["5_intruders"]["median_ms"] <= 50.0,
        "python": platform.python_version(),
        "machine": platform.machine(),
        "results": results,
    }
    out = Path(__file__).resolve().parent / "results" / "bench_reachset.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(report, indent=2))
    for name, r in results.items():
        print(
            f"{name:12s} median {r['median_ms']:7.2f} ms  p90 {r['p90_ms']:7.2f} ms  "
            f"x{r['ratio_to_0_intruders']:.2f}  runs {r['category_runs']}"
        )
    print(f"-> {out}")


if __name__ == "__main__":
    main()
