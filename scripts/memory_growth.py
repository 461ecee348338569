"""What a run keeps in memory as it flies: Python allocations that grew between two sim times.

Flies a scenario with tracemalloc on, snapshots at ``--from`` and ``--to`` [s] of sim time and
prints the allocation sites whose retained size grew most in between (JSBSim's own C++ memory is
not traced; watch the process's RSS for that).

    python scripts/memory_growth.py scenarios/haps_station_june_47n.toml --from 600 --to 2400
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import tracemalloc
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sim.runner import run_scenario  # noqa: E402
from sim.scenario import load_scenario  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario")
    ap.add_argument("--from", dest="t0", type=float, default=600.0, help="first snapshot [s sim]")
    ap.add_argument("--to", dest="t1", type=float, default=2400.0, help="second snapshot [s sim]")
    ap.add_argument("--top", type=int, default=12, help="allocation sites to print")
    args = ap.parse_args()
    if not 0.0 <= args.t0 < args.t1:
        ap.error("--from must be before --to")
    tracemalloc.start(4)
    snaps: dict[float, tracemalloc.Snapshot] = {}

    def hook(t: float) -> None:
        for at in (args.t0, args.t1):
            if at not in snaps and t >= at:
                snaps[at] = tracemalloc.take_snapshot()

    scenario, text = load_scenario(args.scenario)
    with tempfile.TemporaryDirectory() as d:
        run_scenario(scenario, Path(d) / "run.mcap", scenario_text=text, duration=args.t1 + 1.0, tick_hook=hook)
    diff = snaps[args.t1].compare_to(snaps[args.t0], "traceback")
    total = sum(s.size_diff for s in diff)
    print(f"retained Python memory grew {total / 1e6:.2f} MB from {args.t0:g} s to {args.t1:g} s of sim time")
    for stat in diff[: args.top]:
        print(f"{stat.size_diff / 1e6:8.3f} MB {stat.count_diff:+8d} blocks")
        for line in stat.traceback.format()[-4:]:
            print("    ", line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
