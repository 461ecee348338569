"""Log size and logging cost, JSON (the logs before issue #19's compact encoding) against protobuf
(``[logging] encoding``), both flown in the same run on the shipped scenarios (EKF, default rates).

The JSON encoding is the baseline ("before"): it keeps the per-tick path the logs had before
issue #19 (a message dict per topic per tick, encoded with orjson in the simulation process and
handed to the writer process). The protobuf encoding is the compact path: per-tick topics go as
one row of floats per vehicle and tick (:mod:`sim.log_rows`), encoded by the writer process.

Cases (``--case``): ``haps`` (``haps_box_mission``), ``quad`` (``quad_square_mission``) and
``building_lidar`` (``reachset/building_lidar``: the reach-set planner with a LiDAR, its scan
logged at each planner call). Reported per encoding:
- ``mb_per_vehicle_minute``: file size [MB = 1e6 B] / vehicles / sim minutes flown;
- ``logging_share``: CPU time of the simulation process spent logging / its CPU time in the run
  (CPU time, not wall time: on a loaded machine a wall-clock share mostly measures when the
  scheduler preempts the simulation for other processes). Logging = the log task of
  every vehicle (building its messages, incl. the EKF's 3-sigma bounds), the planner-call
  records (threats, LiDAR scan, planner inputs, plans, planner diagnostics), the world's object
  log and the log's close (the writer process finishing the file); nested calls counted once;
- ``logging_us_per_tick``: that logging CPU time per log tick of a vehicle [us] (the share's
  numerator without its denominator, which the machine's load moves between runs);
- ``metrics_share``: the part of ``logging_share`` spent in the run's streaming metrics
  (``TraceRecorder.state`` / ``estimate``, called from the vehicle's log task; the same work in
  both encodings and not logging: the metrics are kept whatever the log holds), and
  ``log_only_share`` = ``logging_share`` - ``metrics_share``;
- ``writer_cpu_s``: CPU time of the writer process (a child: zstd chunks, indexes), off the
  simulation's core.
``ratio``: protobuf / JSON of each figure. Timings depend on the machine's load: compare the two
encodings of one run, not runs.

    python benchmarks/bench_logging.py [--case haps|quad|building_lidar|all] [--repeat 2]
        [--sim-seconds S]
"""

from __future__ import annotations

import argparse
import functools
import json
import resource
import sys
import tempfile
import time
import tomllib
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import sim.mcap_log as mcap_log  # noqa: E402
import sim.vehicle as vehicle  # noqa: E402
import sim.vehicle_log as vehicle_log  # noqa: E402
import sim.world as world  # noqa: E402
from sim.replay.trace import TraceRecorder  # noqa: E402
from sim.runner import run_scenario  # noqa: E402
from sim.scenario import parse_scenario  # noqa: E402

CASES = {  # case: (scenario file, sim seconds)
    "haps": ("haps_box_mission.toml", 300.0),
    "quad": ("quad_square_mission.toml", 60.0),
    "building_lidar": ("reachset/building_lidar.toml", 80.0),
}
ENCODINGS = ("json", "protobuf")
LOGGING = [  # (owner, method): the logging work of a run
    (vehicle.Vehicle, "_log"),
    (world.World, "_log_objects"),
    *((vehicle_log.VehicleLogWriter, m) for m in ("threats", "plan_input", "plan", "latency")),
    *((mcap_log.McapLog, m) for m in ("write_json", "write_proto", "write_record", "event", "close")),
]
METRICS = [(TraceRecorder, "state"), (TraceRecorder, "estimate")]  # inside ``Vehicle._log``


class _Clock:
    """CPU time of this process inside the wrapped methods, outermost calls only."""

    def __init__(self) -> None:
        self.seconds = 0.0
        self.depth = 0

    def wrap(self, fn: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(fn)
        def timed(*args: Any, **kwargs: Any) -> Any:
            if self.depth:  # inside a timed call: not timed again
                return fn(*args, **kwargs)
            self.depth = 1
            t0 = time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                self.seconds += time.process_time() - t0
                self.depth = 0

        return timed


@contextmanager
def clocks() -> Iterator[tuple[_Clock, _Clock]]:
    """The logging clock and the metrics clock (whose calls the logging clock also counts)."""
    logging, metrics = _Clock(), _Clock()
    saved = [
        (owner, name, getattr(owner, name), c)
        for c, table in ((logging, LOGGING), (metrics, METRICS))
        for owner, name in table
    ]
    for owner, name, fn, c in saved:
        setattr(owner, name, c.wrap(fn))
    try:
        yield logging, metrics
    finally:
        for owner, name, fn, _ in saved:
            setattr(owner, name, fn)


def fly(case: str, encoding: str, sim_seconds: float) -> dict[str, float]:
    name, _ = CASES[case]
    data = tomllib.loads((ROOT / "scenarios" / name).read_text())
    data.setdefault("logging", {})["encoding"] = encoding
    scenario = parse_scenario(data, name)
    with tempfile.TemporaryDirectory() as d, clocks() as (clock, metrics):
        path = Path(d) / "bench.mcap"
        cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0, c0 = time.perf_counter(), time.process_time()
        r = run_scenario(scenario, path, duration=sim_seconds)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        size = path.stat().st_size
    minutes = r.sim_time_s / 60.0 * len(scenario.vehicle)
    return {
        "sim_seconds": round(r.sim_time_s, 3),
        "mb_per_vehicle_minute": round(size / 1e6 / minutes, 3),
        "logging_share": round(clock.seconds / cpu, 3),
        "metrics_share": round(metrics.seconds / cpu, 3),
        "log_only_share": round((clock.seconds - metrics.seconds) / cpu, 3),
        "logging_us_per_tick": round(
            clock.seconds / (r.sim_time_s * scenario.logging.rate_hz * len(scenario.vehicle)) * 1e6, 1
        ),
        "writer_cpu_s": round((cpu1.ru_utime + cpu1.ru_stime) - (cpu0.ru_utime + cpu0.ru_stime), 3),
        "wall_s": round(wall, 3),
    }


def measure(case: str, repeat: int, sim_seconds: float | None) -> dict[str, Any]:
    """Each encoding flown ``repeat`` times, alternating; the run with the least logging share
    of each is kept (the least disturbed by the machine's load)."""
    sim_s = sim_seconds or CASES[case][1]
    runs: dict[str, list[dict[str, float]]] = {e: [] for e in ENCODINGS}
    for _ in range(repeat):
        for enc in ENCODINGS:
            runs[enc].append(fly(case, enc, sim_s))
    best = {e: min(rs, key=lambda r: r["logging_share"]) for e, rs in runs.items()}
    out: dict[str, Any] = {"case": case, "scenario": CASES[case][0], **best}
    out["ratio"] = {
        k: round(best["protobuf"][k] / best["json"][k], 3)
        for k in ("mb_per_vehicle_minute", "logging_share", "log_only_share", "logging_us_per_tick", "writer_cpu_s")
        if best["json"][k]
    }
    out["meets_size_target"] = best["protobuf"]["mb_per_vehicle_minute"] <= 1.0
    out["meets_share_target"] = best["protobuf"]["logging_share"] < 0.5 * best["json"]["logging_share"]
    out["meets_share_target_log_only"] = best["protobuf"]["log_only_share"] < 0.5 * best["json"]["log_only_share"]
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--case", choices=[*CASES, "all"], default="all")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--sim-seconds", type=float, default=None, help="override the cases' flight time [s]")
    args = ap.parse_args()
    out = ROOT / "benchmarks" / "results"
    out.mkdir(exist_ok=True)
    for case in CASES if args.case == "all" else [args.case]:
        res = measure(case, args.repeat, args.sim_seconds)
        (out / f"logging_{case}.json").write_text(json.dumps(res, indent=2))
        print(f"[{case}]")
        for k, v in res.items():
            print(f"  {k:22s} {v}")


if __name__ == "__main__":
    main()
