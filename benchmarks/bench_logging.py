"""Log size and logging cost: the current code's two encodings (``[logging] encoding``), JSON and
protobuf, and optionally an older code tree (``--baseline TREE``), all flown in the same run on the
shipped scenarios (EKF, default rates).

Issue #19's "today" is the code it was filed on, commit 5007c63: ``--baseline TREE`` flies a
checkout of it (``git worktree add --detach TREE 5007c63``) beside the current code. The current
code's JSON encoding is a second, weaker baseline: it keeps the shape of the old per-tick path (a
message dict per topic per tick, encoded with orjson in the simulation process), but shares every
speed-up made since. The protobuf encoding is the compact path: per-tick topics go as one row of
floats per vehicle and tick (:mod:`sim.log_rows`), encoded by the writer process.

Every flight is a fresh interpreter started in its tree (importing that tree's ``sim``) that flies
the tree's own copy of the scenario file (``scenario_same_file``: whether it is byte-identical to
the current one). Cases (``--case``): ``haps`` (``haps_box_mission``), ``quad``
(``quad_square_mission``) and ``building_lidar`` (``reachset/building_lidar``: the reach-set
planner with a LiDAR, its scan logged at each planner call). Reported per flight:
- ``mb_per_vehicle_minute``: file size [MB = 1e6 B] / vehicles / sim minutes flown;
- ``logging_share``: CPU time of the simulation process spent logging / its CPU time in the run
  (CPU time, not wall time: on a loaded machine a wall-clock share mostly measures when the
  scheduler preempts the simulation for other processes). Logging is what :data:`ACCOUNTING`
  lists for the tree's code layout, nested calls counted once:
  - current code: the log task of every vehicle (``Vehicle._log``: building its rows or messages,
    the 3-sigma bounds, the streaming metrics it feeds; ``Vehicle.feed_metrics``: the ticks it
    hands the metrics recorder a block at a time, the last at the run's end), the planner-call records
    (``VehicleLogWriter.threats`` / ``plan_input`` / ``plan`` / ``latency`` and the planner's own
    records, ``PlannerType.records`` of :mod:`sim.planner_registry`), the world's object log
    (``World._log_objects``) and every ``McapLog`` write (``write_json`` / ``write_proto`` /
    ``write_record`` / ``event``) and its ``close`` (the writer process finishing the file);
  - 5007c63: the same work under that tree's names: ``Vehicle._log`` (its ``tracking``,
    ``truth``, ``estimate``, ``sensors`` with the 3-sigma bounds, ``control``, ``mission`` writes
    and the metrics it feeds), ``VehicleLogWriter.threats`` / ``plan`` (which wrote the latency
    too), ``PlannerLogger.write`` (the planner's own records), ``World._log_objects`` and
    ``McapLog.write_json`` / ``write_proto`` / ``event`` / ``close``;
- ``logging_us_per_tick``: that logging CPU time per log tick of a vehicle [us] (the share's
  numerator without its denominator, which the machine's load and the rest of the code move);
- ``metrics_share``: the part of ``logging_share`` spent in the run's metrics
  (``TraceRecorder.state`` / ``estimate``, called from the vehicle's log task), and
  ``log_only_share`` = ``logging_share`` - ``metrics_share``;
- ``writer_cpu_s``: CPU time of the writer process (a child: zstd chunks, indexes), off the
  simulation's core.
Each configuration is flown ``--repeat`` times, the configurations alternating; the flight with
the least logging share of each is kept (the least disturbed by the load) and ``shares`` lists
them all. ``ratio``: protobuf / JSON of each figure; ``ratio_to_baseline``: protobuf / baseline
tree. Timings depend on the machine's load: compare the configurations of one run, not runs.

    python benchmarks/bench_logging.py [--case haps|quad|building_lidar|all] [--repeat 2]
        [--sim-seconds S] [--baseline TREE]
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import importlib
import json
import resource
import subprocess
import sys
import tempfile
import time
import tomllib
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]

CASES = {  # case: (scenario file, sim seconds)
    "haps": ("haps_box_mission.toml", 300.0),
    "quad": ("quad_square_mission.toml", 60.0),
    "building_lidar": ("reachset/building_lidar.toml", 80.0),
}
ENCODINGS = ("json", "protobuf")
BASELINE = "baseline"
_LOG_WRITES = ("write_json", "write_proto", "event", "close")
# code layout: (the file that tells it, logging methods, metrics methods inside the log task);
# methods as (module, class, method)
ACCOUNTING: dict[str, tuple[str, list[tuple[str, str, str]], list[tuple[str, str, str]]]] = {
    "current": (
        "sim/planner_records.py",
        [
            ("sim.vehicle", "Vehicle", "_log"),
            ("sim.vehicle", "Vehicle", "feed_metrics"),
            ("sim.world", "World", "_log_objects"),
            *(("sim.vehicle_log", "VehicleLogWriter", m) for m in ("threats", "plan_input", "plan", "latency")),
            *(("sim.mcap_log", "McapLog", m) for m in (*_LOG_WRITES, "write_record")),
        ],
        [("sim.replay.trace", "TraceRecorder", m) for m in ("state", "estimate")],
    ),
    "5007c63": (
        "sim/planner_log.py",
        [
            ("sim.vehicle", "Vehicle", "_log"),
            ("sim.world", "World", "_log_objects"),
            *(("sim.vehicle_log", "VehicleLogWriter", m) for m in ("threats", "plan")),
            ("sim.planner_log", "PlannerLogger", "write"),
            *(("sim.mcap_log", "McapLog", m) for m in _LOG_WRITES),
        ],
        [("sim.replay.trace", "TraceRecorder", m) for m in ("state", "estimate")],
    ),
}


RECENT = {"feed_metrics"}  # methods of the current layout that its older trees lack


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


def layout(tree: Path) -> str:
    """The code layout of ``tree`` (a key of :data:`ACCOUNTING`)."""
    for name, (marker, _, _) in ACCOUNTING.items():
        if (tree / marker).is_file():
            return name
    raise SystemExit(f"{tree}: unknown code layout (none of {[m for m, _, _ in ACCOUNTING.values()]})")


@contextmanager
def clocks(code: str) -> Iterator[tuple[_Clock, _Clock]]:
    """The logging clock and the metrics clock (whose calls the logging clock also counts) on the
    methods :data:`ACCOUNTING` lists for layout ``code``; in the current layout also on each
    planner type's own record writer."""
    logging, metrics = _Clock(), _Clock()
    _, logged, metered = ACCOUNTING[code]
    saved = []
    for c, table in ((logging, logged), (metrics, metered)):
        for module, cls, name in table:
            owner = getattr(importlib.import_module(module), cls)
            if name in RECENT and not hasattr(owner, name):
                continue
            saved.append((owner, name, getattr(owner, name), c))
    for owner, name, fn, c in saved:
        setattr(owner, name, c.wrap(fn))
    planners: dict[str, Any] = {}
    if code == "current":
        planners = importlib.import_module("sim.planner_registry").PLANNERS
    kept = dict(planners)
    for name, entry in kept.items():
        if entry.records is not None:
            planners[name] = dataclasses.replace(entry, records=logging.wrap(entry.records))
    try:
        yield logging, metrics
    finally:
        for owner, name, fn, _ in saved:
            setattr(owner, name, fn)
        planners.update(kept)


def fly_here(case: str, encoding: str | None, sim_seconds: float) -> dict[str, Any]:
    """Fly ``case`` with the ``sim`` on ``sys.path`` (its tree's scenario file; ``encoding``
    None: the tree's only encoding) and measure it."""
    import sim
    from sim.runner import run_scenario
    from sim.scenario import parse_scenario

    tree = Path.cwd()
    if not Path(sim.__file__).resolve().is_relative_to(tree.resolve()):
        raise SystemExit(f"{tree}: imported the sim of {sim.__file__} instead of this tree's")
    name, _ = CASES[case]
    text = Path("scenarios", name).read_text()
    data = tomllib.loads(text)
    if encoding is not None:
        data.setdefault("logging", {})["encoding"] = encoding
    scenario = parse_scenario(data, name)
    code = layout(tree)
    with tempfile.TemporaryDirectory() as d, clocks(code) as (clock, metrics):
        path = Path(d) / "bench.mcap"
        cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0, c0 = time.perf_counter(), time.process_time()
        r = run_scenario(scenario, path, duration=sim_seconds)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        size = path.stat().st_size
    minutes = r.sim_time_s / 60.0 * len(scenario.vehicle)
    ticks = r.sim_time_s * scenario.logging.rate_hz * len(scenario.vehicle)
    return {
        "code": code,
        "scenario_same_file": text == (ROOT / "scenarios" / name).read_text(),
        "sim_seconds": round(r.sim_time_s, 3),
        "mb_per_vehicle_minute": round(size / 1e6 / minutes, 3),
        "logging_share": round(clock.seconds / cpu, 4),
        "metrics_share": round(metrics.seconds / cpu, 4),
        "log_only_share": round((clock.seconds - metrics.seconds) / cpu, 4),
        "logging_us_per_tick": round(clock.seconds / ticks * 1e6, 1),
        "cpu_us_per_tick": round(cpu / ticks * 1e6, 1),
        "writer_cpu_s": round((cpu1.ru_utime + cpu1.ru_stime) - (cpu0.ru_utime + cpu0.ru_stime), 3),
        "wall_s": round(wall, 3),
    }


def fly(tree: Path, case: str, encoding: str | None, sim_seconds: float) -> dict[str, Any]:
    """:func:`fly_here` in a fresh interpreter started in ``tree``."""
    cmd = [sys.executable, str(Path(__file__).resolve()), "--fly", case, encoding or "-", str(sim_seconds)]
    done = subprocess.run(cmd, check=False, cwd=tree.resolve(), capture_output=True, text=True)
    if done.returncode:
        raise SystemExit(f"{tree}: the {case} flight failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


FIGURES = ("mb_per_vehicle_minute", "logging_share", "log_only_share", "logging_us_per_tick", "writer_cpu_s")


def _ratio(a: dict[str, Any], b: dict[str, Any]) -> dict[str, float]:
    return {k: round(a[k] / b[k], 3) for k in FIGURES if b[k]}


def measure(case: str, repeat: int, sim_seconds: float | None, baseline: Path | None) -> dict[str, Any]:
    """Each configuration (the current code's encodings, the baseline tree) flown ``repeat``
    times, alternating; the flight with the least logging share of each is kept."""
    sim_s = sim_seconds or CASES[case][1]
    configs: dict[str, tuple[Path, str | None]] = {e: (ROOT, e) for e in ENCODINGS}
    if baseline is not None:
        configs[BASELINE] = (baseline, None)
    runs: dict[str, list[dict[str, Any]]] = {c: [] for c in configs}
    for _ in range(repeat):
        for c, (tree, enc) in configs.items():
            runs[c].append(fly(tree, case, enc, sim_s))
    best = {c: min(rs, key=lambda r: r["logging_share"]) for c, rs in runs.items()}
    for c, rs in runs.items():
        best[c]["shares"] = [r["logging_share"] for r in rs]
    out: dict[str, Any] = {"case": case, "scenario": CASES[case][0], **best}
    new = best["protobuf"]
    out["ratio"] = _ratio(new, best["json"])
    out["meets_size_target"] = new["mb_per_vehicle_minute"] <= 1.0
    out["meets_share_target"] = new["logging_share"] < 0.5 * best["json"]["logging_share"]
    if baseline is not None:
        old = best[BASELINE]
        out["baseline_tree"] = str(baseline)
        out["ratio_to_baseline"] = _ratio(new, old)
        out["meets_share_target_vs_baseline"] = new["logging_share"] < 0.5 * old["logging_share"]
    return out


def main() -> None:
    if sys.argv[1:2] == ["--fly"]:  # a flight of this tree's code: one JSON line on stdout
        case, encoding, seconds = sys.argv[2:5]
        sys.path.insert(0, str(Path.cwd()))
        print(json.dumps(fly_here(case, None if encoding == "-" else encoding, float(seconds))))
        return
    ap = argparse.ArgumentParser()
    ap.add_argument("--case", choices=[*CASES, "all"], default="all")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--sim-seconds", type=float, default=None, help="override the cases' flight time [s]")
    ap.add_argument("--baseline", type=Path, default=None, help="an older code tree flown beside (e.g. 5007c63)")
    args = ap.parse_args()
    if args.baseline is not None and not (args.baseline / "sim").is_dir():
        raise SystemExit(f"--baseline {args.baseline}: not a code tree (no sim/ in it)")
    out = ROOT / "benchmarks" / "results"
    out.mkdir(exist_ok=True)
    for case in CASES if args.case == "all" else [args.case]:
        res = measure(case, args.repeat, args.sim_seconds, args.baseline)
        (out / f"logging_{case}.json").write_text(json.dumps(res, indent=2))
        print(f"[{case}]")
        for k, v in res.items():
            print(f"  {k:22s} {v}")


if __name__ == "__main__":
    main()
