"""Closed-loop avoidance quality of the current intruder rating against the previous one
(``bench_reachset.LatticeIntruderModel``, swapped in for the ``baseline`` rows): every shipped
reach-set and rules scenario with traffic, flown to its end on the EKF estimates; per run the
pairwise minimum separations [m] and the mission times [s] (replay metrics of the MCAP) and the
wall time [s]. Writes benchmarks/results/compare_reachset_quality.json.

    python benchmarks/compare_reachset_quality.py [--paths baseline,current] [--scenarios s7_head_on,...]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_reachset import code_path  # noqa: E402

from sim.replay.report import log_metrics  # noqa: E402
from sim.runner import run_scenario  # noqa: E402
from sim.scenario import load_scenario  # noqa: E402

SCENARIOS = [
    "reachset/s6_converging",
    "reachset/s7_head_on",
    "reachset/s8_head_on_four",
    "rules/s9_converging",
    "rules/s10_head_on",
    "rules/s11_roundabout",
    "rules/s12_overtake_2x",
    "rules/s13_overtake_3x",
    "rules/s13_overtake_4x",
    "rules/s14_pursuer",
    "rules/mixed_haps_swarm",
]


def fly(name: str) -> dict:
    scenario, text = load_scenario(ROOT / "scenarios" / f"{name}.toml")
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "run.mcap"
        r = run_scenario(scenario, out, scenario_text=text)
        m = log_metrics(out)
    return {
        "separation_m": {k: round(v["distance_m"], 2) for k, v in m["separation"].items()},
        "mission_s": {
            k: (round(v["mission"]["time_s"], 1) if v["mission"]["complete"] else None)
            for k, v in m["vehicles"].items()
        },
        "wall_s": round(r.wall_time_s, 1),
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--paths", default="baseline,current")
    ap.add_argument("--scenarios", default=",".join(SCENARIOS))
    args = ap.parse_args()
    out = ROOT / "benchmarks" / "results" / "compare_reachset_quality.json"
    results = json.loads(out.read_text()) if out.exists() else {}
    for name in args.scenarios.split(","):
        for path in args.paths.split(","):
            with code_path(path):
                res = fly(name)
            results.setdefault(name, {})[path] = res
            out.parent.mkdir(parents=True, exist_ok=True)
            out.write_text(json.dumps(results, indent=2))
            sep = min(res["separation_m"].values(), default=float("nan"))
            print(f"{name:28s} {path:9s} min sep {sep:7.2f} m  missions {res['mission_s']}  wall {res['wall_s']} s")
    print(f"-> {out}")


if __name__ == "__main__":
    main()
