"""Where a closed-loop run's time goes: CPU time per scheduler task and plant, as shares of the
scheduler's loop (``sched overhead``: the loop itself and what no task accounts for).

Flies ``scenarios/<SCENARIO>.toml`` (as shipped) for ``--sim-seconds`` with a CPU-time timer around
every task and plant step of the lockstep scheduler; the timers add a little to every entry.

    python benchmarks/task_split.py mixed_haps_quad_reachset --sim-seconds 60
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import tomllib
from collections import Counter
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import sim.runner as runner  # noqa: E402
import sim.scheduler as scheduler  # noqa: E402
from sim.scenario import parse_scenario  # noqa: E402

cpu: Counter[str] = Counter()
calls: Counter[str] = Counter()


def timed(name: str, fn: Callable) -> Callable:
    def run(*args):
        c0 = time.process_time()
        out = fn(*args)
        cpu[name] += time.process_time() - c0
        calls[name] += 1
        return out

    return run


class TimedScheduler(scheduler.LockstepScheduler):
    def add_plant(self, name, rate_hz, step):
        super().add_plant(name, rate_hz, timed(name, step))

    def add_task(self, name, rate_hz, stage, fn, plant=None):
        super().add_task(name, rate_hz, stage, timed(name, fn), plant)

    def run(self, until_tick, stop=lambda: False):
        c0 = time.process_time()
        super().run(until_tick, stop)
        cpu["TOTAL"] += time.process_time() - c0


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("scenario", help="a shipped scenario name (scenarios/<name>.toml)")
    ap.add_argument("--sim-seconds", type=float, default=60.0)
    args = ap.parse_args()
    data = tomllib.loads((ROOT / "scenarios" / f"{args.scenario}.toml").read_text())
    runner.LockstepScheduler = TimedScheduler  # type: ignore[misc]  # the scheduler the runner builds
    with tempfile.TemporaryDirectory() as d:
        runner.run_scenario(parse_scenario(data, args.scenario), Path(d) / "split.mcap", duration=args.sim_seconds)
    total = cpu.pop("TOTAL")
    cpu["sched overhead"] = total - sum(cpu.values())
    print(f"{args.scenario}, {args.sim_seconds:g} s: scheduler loop {total:.2f} s CPU")
    for name, t in cpu.most_common():
        print(f"  {name:24s} {t:7.3f} s  {100 * t / total:5.1f} %  calls {calls[name]}")


if __name__ == "__main__":
    main()
