"""MPTP search cost by turn model: the first replan of the thesis's scenarios 1 and 2 (open loop,
SSPH) with ``turn_model`` simple, approximate and simulated, interleaved and repeated; the best
search time per expansion and its ratio to the simple model's in the same run (the thesis's
80 m/s aircraft, the HAPS roll rate 6 deg/s for the simulated turns).

    python benchmarks/bench_mptp_turn_models.py [--repeat N]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from guidance.mptp.search import plan_trajectory  # noqa: E402
from guidance.mptp.timeline import ObstacleTimeline  # noqa: E402
from sim.testbeds import mptp_thesis as S  # noqa: E402

MODELS = ("simple", "approximate", "simulated")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    print("| scenario | turn model | EXST | status | best search [s] | per expansion [ms] | ratio to simple |")
    print("|---|---|---|---|---|---|---|")
    for make in (S.scenario_1, S.scenario_2):
        sc = make()
        snaps = sc.storms.nowcast(0.0)
        best: dict[str, tuple[float, int, str]] = {}
        for _ in range(args.repeat):
            for model in MODELS:
                cfg = sc.cfg.with_(turn_model=model)
                tl = ObstacleTimeline(snaps, cfg, 2 * cfg.horizon_s)
                tr = plan_trajectory(tl, sc.start, 0.0, sc.course, sc.goal, cfg)
                if model not in best or tr.runtime_s < best[model][0]:
                    best[model] = (tr.runtime_s, tr.expanded, tr.status)
        base = best["simple"][0] / max(best["simple"][1], 1)
        for model in MODELS:
            s, n, status = best[model]
            per = s / max(n, 1)
            print(f"| {sc.name} | {model} | {n} | {status} | {s:.2f} | {1000 * per:.0f} | {per / base:.2f} |")


if __name__ == "__main__":
    main()
