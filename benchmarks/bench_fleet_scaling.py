"""Fleet cost against fleet size: is the closed loop linear in the number of reach-set vehicles?

Flies the first N vehicles (N = 2, 4, 8: whole head-on pairs) of the shipped
``scenarios/reachset_fleet8.toml`` (eight quadrotors on the reach-set planner, four head-on pairs
500 m apart, EKF, logging) and reports the wall time per vehicle per simulated second, beside
bare JSBSim stepping of one of this project's quadrotors (the same model, 240 Hz) measured
in the same run (``vehicle_cost_to_bare``:
closed-loop wall per vehicle-second over bare wall per vehicle-second). Linear fleet cost means
that ratio stays flat as N grows. ``--paths baseline,current`` also flies the world without the
broad phase of issue #16 (every vehicle senses every other body), where each vehicle's sensing,
tracking and rating grow with N (cost ∝ N²).

    python benchmarks/bench_fleet_scaling.py [--sizes 2,4,8] [--sim-seconds 20] [--repeat 1]
        [--paths current|baseline,current]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_closed_loop import QUAD, bare_steps_per_s, broad_phase  # noqa: E402

from sim.runner import run_scenario  # noqa: E402
from sim.scenario import parse_scenario  # noqa: E402

SCENARIO = ROOT / "scenarios" / "reachset_fleet8.toml"


def wall_per_vehicle_second(n: int, sim_seconds: float) -> float:
    """Closed-loop wall time [s] per vehicle per simulated second of the fleet's first ``n``."""
    data = tomllib.loads(SCENARIO.read_text())
    if not 1 <= n <= len(data["vehicle"]):
        raise SystemExit(f"--sizes: {n} is not between 1 and {len(data['vehicle'])}")
    data["vehicle"] = data["vehicle"][:n]
    scenario = parse_scenario(data, f"fleet{n}")
    with tempfile.TemporaryDirectory() as d:
        r = run_scenario(scenario, Path(d) / "fleet.mcap", duration=sim_seconds)
    return r.wall_time_s / (r.sim_time_s * n)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="2,4,8", help="comma-separated fleet sizes (first N vehicles)")
    ap.add_argument("--sim-seconds", type=float, default=20.0)
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--paths", default="current", help="comma-separated: baseline (no broad phase), current")
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    model, airframe, rate = QUAD
    bare = 1.0 / max(bare_steps_per_s(model, airframe, rate, int(args.sim_seconds * rate)) for _ in range(3))
    bare_vehicle_second = bare * rate
    out: dict = {
        "scenario": SCENARIO.name,
        "sim_seconds": args.sim_seconds,
        "bare_wall_per_vehicle_second": bare_vehicle_second,
    }
    for path in args.paths.split(","):
        rows = []
        with broad_phase(path):
            for n in sizes:
                w = min(wall_per_vehicle_second(n, args.sim_seconds) for _ in range(args.repeat))
                rows.append(
                    {
                        "n": n,
                        "wall_per_vehicle_second": round(w, 4),
                        "vehicle_cost_to_bare": round(w / bare_vehicle_second, 1),
                    }
                )
        first = rows[0]["wall_per_vehicle_second"]
        for row in rows:
            row["per_vehicle_cost_vs_smallest"] = round(row["wall_per_vehicle_second"] / first, 2)
        out[path] = rows
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
