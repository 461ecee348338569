"""Reading a run log in log-time order: cosim's chunk-by-chunk order against the MCAP library's
merge, on the same log in the same run (the ratio does not depend on the machine's load).

Flies the shipped ``scenarios/haps_box_mission.toml`` for ``--duration`` (default 900 s), then
reads every message of the log (``sim.mcap_read.iter_messages``: decoded, in log-time order)
``--repeat`` times each way, alternating, and reports the CPU time of each and their ratio. Both
ways give the same messages in the same order (checked here; tests/test_mcap_order.py).

    python benchmarks/bench_log_read.py [--duration 900] [--repeat 3] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from sim import mcap_read
from sim.runner import run_scenario
from sim.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "haps_box_mission.toml"


def _library(reader, f, summary, topics):  # the signature of sim.mcap_order.messages_in_log_time_order
    return reader.iter_messages(topics=topics, log_time_order=True)


def _read(path: Path, order: Callable) -> tuple[float, list[tuple[str, float]]]:
    """CPU time [s] of reading every message with ``order``, and (topic, time) of each."""
    chunked = mcap_read.messages_in_log_time_order
    mcap_read.messages_in_log_time_order = order
    try:
        t0 = time.process_time()
        seen = [(topic, t) for topic, t, _ in mcap_read.iter_messages(path)]
        return time.process_time() - t0, seen
    finally:
        mcap_read.messages_in_log_time_order = chunked


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--duration", type=float, default=900.0, help="sim time flown [s]")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "run.mcap"
        scenario, text = load_scenario(SCENARIO)
        run_scenario(scenario, log, scenario_text=text, duration=args.duration)
        times: dict[str, list[float]] = {"chunked": [], "library": []}
        orders = {"chunked": mcap_read.messages_in_log_time_order, "library": _library}
        seen: dict[str, list] = {}
        for _ in range(args.repeat):
            for name, order in orders.items():
                dt, seen[name] = _read(log, order)
                times[name].append(dt)
        if seen["chunked"] != seen["library"]:
            raise SystemExit("the two orders differ")
        med = {k: statistics.median(v) for k, v in times.items()}
        result = {
            "scenario": str(SCENARIO.relative_to(ROOT)),
            "duration_s": args.duration,
            "messages": len(seen["chunked"]),
            "log_mib": log.stat().st_size / 2**20,
            "cpu_s_median": med,
            "library_over_chunked": med["library"] / med["chunked"],
        }
    print(json.dumps(result, indent=2))
    if args.json:
        args.json.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
