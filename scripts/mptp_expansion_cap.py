"""The MPTP's expansion cap against its replan time and its plans: the data for a choice.

The worst replans of the thesis-sized scenarios are the searches that stop at the expansion cap
(120, docs/mptp.md "Replan speed"); a lower cap shortens them and changes the plans. For each
cap, each thesis scenario is replanned open loop (``sim/testbeds/mptp_openloop.py``) in a steady
true wind that the planner is also given as its forecast, with ``MptpConfig.max_expansions`` set
to the cap; per run it reports the number of replans, the worst and mean process CPU time of
``MptpPlanner._replan`` [s], the arrival time [min] and the ground length flown [km] (NaN
arrival: not arrived within the scenario's replans).

    python scripts/mptp_expansion_cap.py --caps 120,90,60,45,30 [--wind 9,12]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from guidance.mptp.planner import MptpPlanner
from guidance.mptp.wind import WindForecast
from sim.testbeds import mptp_thesis
from sim.testbeds.mptp_openloop import run_open_loop

SCENARIOS = ("scenario_1", "scenario_2", "holding_scenario", "moving_goal_scenario")


def one_run(scenario: str, cap: int, wind: np.ndarray) -> dict:
    """Worst / mean CPU per replan [s], arrival [s] and flown length [m] at expansion cap ``cap``."""
    cpu: list[float] = []
    replan = MptpPlanner._replan

    def timed(self, *args, **kwargs):
        c = time.process_time()
        out = replan(self, *args, **kwargs)
        cpu.append(time.process_time() - c)
        return out

    sc = getattr(mptp_thesis, scenario)()
    sc = dataclasses.replace(sc, cfg=dataclasses.replace(sc.cfg, max_expansions=cap))
    MptpPlanner._replan = timed  # type: ignore[method-assign]
    try:
        run = run_open_loop(sc, wind_true=wind, wind_forecast=WindForecast.steady(*wind))
    finally:
        MptpPlanner._replan = replan  # type: ignore[method-assign]
    return {
        "worst_cpu_s": max(cpu),
        "mean_cpu_s": float(np.mean(cpu)),
        "replans": len(cpu),
        "arrival_s": run.arrived_s,
        "length_m": run.length_m,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--caps", default="120,90,60,45,30", help="comma-separated expansion caps")
    ap.add_argument("--wind", default="9,12", help="true and forecast wind (north, east) [m/s]")
    ap.add_argument("--scenarios", default=",".join(SCENARIOS))
    a = ap.parse_args()
    wind = np.array([float(x) for x in a.wind.split(",")])
    caps = [int(c) for c in a.caps.split(",")]
    if not caps or min(caps) < 1:
        ap.error("--caps must be positive integers")
    print("| scenario | cap | replans | worst CPU [s] | mean CPU [s] | arrival [min] | flown [km] |")
    print("|---|---|---|---|---|---|---|")
    for scenario in a.scenarios.split(","):
        for cap in caps:
            r = one_run(scenario, cap, wind)
            print(
                f"| {scenario} | {cap} | {r['replans']} | {r['worst_cpu_s']:.2f} | {r['mean_cpu_s']:.2f} | "
                f"{r['arrival_s'] / 60:.1f} | {r['length_m'] / 1000:.1f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
