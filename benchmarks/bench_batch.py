"""Batch throughput: a small HAPS Monte-Carlo on a local process pool, 1 worker vs 2.

Uses ``sim.batch.load_batch`` on ``scenarios/batch/haps_monte_carlo.toml`` (the first ``--runs``
runs, each flown for ``--duration`` s of sim time instead of the file's 5 min), then
``run_batch(..., workers=1)`` and ``workers=2`` into fresh temporary folders (no resume).
Reported: wall time, runs/min, the speed-up ratio, and whether both batches gave identical
per-run metrics. JSON: benchmarks/results/batch.json.

    python benchmarks/bench_batch.py [--runs 8] [--duration 300]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sim.batch import load_batch, run_batch  # noqa: E402 (after the sys.path line: runs as a script)

BATCH = ROOT / "scenarios" / "batch" / "haps_monte_carlo.toml"


def measure(runs, workers: int) -> tuple[float, list[dict]]:
    with tempfile.TemporaryDirectory() as tmp:
        specs = [
            dataclasses.replace(
                s,
                log_path=str(Path(tmp) / "runs" / f"{s.run_id}.mcap"),
                result_path=str(Path(tmp) / "runs" / f"{s.run_id}.json"),
            )
            for s in runs
        ]
        t0 = time.perf_counter()
        rows = run_batch(specs, tmp, workers=workers, resume=False)
        return time.perf_counter() - t0, rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=8)
    ap.add_argument("--duration", type=float, default=300.0, help="sim time per run [s] (the file: 5 min)")
    args = ap.parse_args(argv)
    _name, runs = load_batch(BATCH)
    runs = [dataclasses.replace(r, duration=args.duration) for r in runs[: args.runs]]
    result = {
        "batch": str(BATCH.relative_to(ROOT)),
        "runs": len(runs),
        "sim_seconds_per_run": args.duration,
        "cpu_count": os.cpu_count(),
        "machine": platform.processor() or platform.machine(),
        "python": platform.python_version(),
    }
    rows_by = {}
    for workers in (1, 2):
        wall, rows = measure(runs, workers)
        failed = sum(r.get("status") == "failed" for r in rows)
        result[f"workers_{workers}"] = {
            "wall_s": round(wall, 2),
            "runs_per_min": round(60 * len(runs) / wall, 2),
            "failed": failed,
        }
        rows_by[workers] = rows
        print(f"workers={workers}: {wall:.1f} s, {60 * len(runs) / wall:.1f} runs/min, {failed} failed")
    result["speedup_2_vs_1"] = round(result["workers_1"]["wall_s"] / result["workers_2"]["wall_s"], 3)

    def strip(r):
        return {k: v for k, v in r.items() if "wall" not in k and "latency" not in k and "runtime" not in k}

    result["identical_metrics"] = [strip(r) for r in rows_by[1]] == [strip(r) for r in rows_by[2]]
    print(f"speed-up 2 vs 1 worker: {result['speedup_2_vs_1']:.2f}; identical metrics: {result['identical_metrics']}")
    out = ROOT / "benchmarks" / "results" / "batch.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
