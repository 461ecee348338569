"""MPTP replan time in wind on the thesis-sized scenarios: this code against a baseline checkout.

    git worktree add --detach /tmp/mptp-base bf91794   # main before the replan speed-ups
    python benchmarks/bench_mptp_replan.py --baseline /tmp/mptp-base [--wind 9,12] [--repeat 2]
        [--scenarios scenario_1,scenario_2,holding_scenario,moving_goal_scenario]

Each scenario is replanned open loop (sim/testbeds/mptp_openloop.py: the thesis's chapter-6 runs,
80 m/s aircraft, a fresh nowcast every replan) in a steady true wind that the planner is also
given as its forecast (air-mass frame), once with this checkout's code and once with the
baseline's, each in its own process (the code is imported from that checkout), alternating
between the two ``--repeat`` times so that load changes hit both alike. Per replan it records the
wall clock and the process CPU time of ``MptpPlanner._replan`` (weather + search; CPU time is
less disturbed by other jobs on a shared machine) and the plan. It prints, per scenario, the
worst replan of each code (the best of the repeats, per replan), their ratio, and whether the
plans are the same (largest vertex distance between the two codes' plans, and the number of
replans whose plans differ in status or vertex count). Writes
benchmarks/results/mptp_replan.json.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ("scenario_1", "scenario_2", "holding_scenario", "moving_goal_scenario")


def worker(root: Path, scenario: str, wind: tuple[float, float]) -> dict:
    """Replans of ``scenario`` with the code of checkout ``root``: per-replan wall and CPU
    time [s] and each plan's vertices (north, east) [m], times [s] and status."""
    import time

    sys.path.insert(0, str(root))
    from guidance.mptp.planner import MptpPlanner
    from guidance.mptp.wind import WindForecast
    from sim.testbeds import mptp_thesis
    from sim.testbeds.mptp_openloop import run_open_loop

    wall: list[float] = []
    cpu: list[float] = []
    replan = MptpPlanner._replan

    def timed(self, *args, **kwargs):
        w, c = time.perf_counter(), time.process_time()
        out = replan(self, *args, **kwargs)
        cpu.append(time.process_time() - c)
        wall.append(time.perf_counter() - w)
        return out

    MptpPlanner._replan = timed  # type: ignore[method-assign]
    w = np.array(wind, float)
    run = run_open_loop(getattr(mptp_thesis, scenario)(), wind_true=w, wind_forecast=WindForecast.steady(*w))
    return {
        "wall_s": wall,
        "cpu_s": cpu,
        "plans": [
            {"ne": p.positions[:, :2].tolist(), "times": p.times.tolist(), "status": p.status.value} for p in run.plans
        ],
        "arrival_s": run.arrived_s,
    }


def run_worker(root: Path, scenario: str, wind: tuple[float, float]) -> dict:
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", scenario, "--root", str(root)]
    cmd += ["--wind", f"{wind[0]},{wind[1]}"]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True, cwd=root).stdout
    return json.loads(out.splitlines()[-1])


def plan_difference(a: list[dict], b: list[dict]) -> tuple[float, int]:
    """Largest vertex distance [m] between plans of the same replan with the same vertex count,
    and the number of replans whose plans differ in count, status or vertex count."""
    worst, differ = 0.0, abs(len(a) - len(b))
    for pa, pb in zip(a, b, strict=False):
        if pa["status"] != pb["status"] or len(pa["ne"]) != len(pb["ne"]):
            differ += 1
            continue
        d = float(np.linalg.norm(np.subtract(pa["ne"], pb["ne"]), axis=1).max()) if pa["ne"] else 0.0
        worst = max(worst, d)
        differ += d > 1e-6
    return worst, differ


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--baseline", type=Path, help="checkout of the code to compare with (e.g. a git worktree)")
    ap.add_argument("--wind", default="9,12", help="true and forecast wind (north, east) [m/s]")
    ap.add_argument("--repeat", type=int, default=1, help="runs per code and scenario (best per replan)")
    ap.add_argument("--scenarios", default=",".join(SCENARIOS))
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument("--root", type=Path, help=argparse.SUPPRESS)
    a = ap.parse_args()
    n, e = (float(x) for x in a.wind.split(","))
    if a.worker:
        print(json.dumps(worker(a.root, a.worker, (n, e))))
        return
    if a.baseline is None or not (a.baseline / "guidance" / "mptp").is_dir():
        ap.error("--baseline must be a checkout of this repository (with guidance/mptp)")
    if a.repeat < 1:
        ap.error("--repeat must be >= 1")
    codes = {"new": ROOT, "baseline": a.baseline.resolve()}
    rows = []
    for sc in a.scenarios.split(","):
        runs: dict[str, list[dict]] = {k: [] for k in codes}
        for _ in range(a.repeat):
            for k, root in codes.items():
                runs[k].append(run_worker(root, sc, (n, e)))
        row: dict = {"scenario": sc, "replans": len(runs["new"][0]["wall_s"])}
        for k in codes:
            for m in ("wall_s", "cpu_s"):
                best = np.min([r[m] for r in runs[k]], axis=0)
                row[f"{k}_worst_{m}"] = float(best.max())
                row[f"{k}_mean_{m}"] = float(best.mean())
        row["ratio_worst_cpu"] = row["baseline_worst_cpu_s"] / row["new_worst_cpu_s"]
        row["ratio_mean_cpu"] = row["baseline_mean_cpu_s"] / row["new_mean_cpu_s"]
        row["max_vertex_diff_m"], row["replans_differing"] = plan_difference(
            runs["new"][0]["plans"], runs["baseline"][0]["plans"]
        )
        row["arrival_new_s"], row["arrival_baseline_s"] = runs["new"][0]["arrival_s"], runs["baseline"][0]["arrival_s"]
        rows.append(row)
    out = ROOT / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    (out / "mptp_replan.json").write_text(json.dumps({"wind": [n, e], "repeat": a.repeat, "rows": rows}, indent=1))
    print(
        "| scenario | replans | worst CPU base / new [s] | speed-up | mean CPU base / new [s] | speed-up "
        "| worst wall base / new [s] | plans differing | largest vertex shift [m] |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['scenario']} | {r['replans']} | {r['baseline_worst_cpu_s']:.2f} / {r['new_worst_cpu_s']:.2f} | "
            f"{r['ratio_worst_cpu']:.2f} | {r['baseline_mean_cpu_s']:.2f} / {r['new_mean_cpu_s']:.2f} | "
            f"{r['ratio_mean_cpu']:.2f} | {r['baseline_worst_wall_s']:.2f} / {r['new_worst_wall_s']:.2f} | "
            f"{r['replans_differing']} | {r['max_vertex_diff_m']:.3g} |"
        )


if __name__ == "__main__":
    main()
