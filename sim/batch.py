"""Batch runs: parameter sweeps and Monte-Carlo over a base scenario, on any Executor.

A batch file (TOML) names a base scenario and what to vary::

    base = "../scenarios/haps_box_mission.toml"   # relative to the batch file
    name = "haps_speed_sweep"
    duration = "10 min"                            # optional: overrides the scenario's

    [sweep]                                        # full grid over the listed values
    "vehicle.0.mission.cruise_speed" = ["24 m/s", "26 m/s", "28 m/s"]

    [monte_carlo]                                  # N draws (crossed with the sweep grid)
    runs = 20
    seed = 7                                       # master seed: run seeds derive from it
    [monte_carlo.uniform]
    "vehicle.0.initial.heading" = [0, 360]         # uniform in [lo, hi] (bare numbers: field units)
    [monte_carlo.normal]
    "vehicle.0.initial.airspeed" = [26, 0.5]       # mean, standard deviation

Keys are dotted paths into the scenario (list indices as numbers). Every run is a full, validated
scenario with its own seed, logged to ``<out>/runs/<run id>.mcap``; its metrics go to
``<out>/runs/<run id>.json`` (written last, atomically: a run with a JSON is finished and is
skipped on resume) and all rows to ``<out>/results.csv``. A run that raises is recorded as failed;
the others go on. Runs go through any ``concurrent.futures.Executor``: a process pool by default,
or a Dask ``distributed`` cluster (``Client(address).get_executor()``).
"""

from __future__ import annotations

import copy
import csv
import itertools
import json
import os
import tomllib
from collections.abc import Callable, Iterable
from concurrent.futures import Executor, ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tomli_w

from sim.replay.metrics import flatten
from sim.scenario import ScenarioError, parse_scenario
from sim.units import to_si


class BatchError(ValueError):
    """The batch file is invalid; the message names the file and the key."""


@dataclass(frozen=True, slots=True)
class RunSpec:
    """One run of a batch: id, the scenario mapping to fly, where to log, what was varied."""

    run_id: str
    scenario: dict
    duration: float | None
    log_path: str
    result_path: str
    params: dict


def _set_path(data: dict, dotted: str, value, source: str) -> None:
    keys = [int(k) if k.isdigit() else k for k in dotted.split(".")]
    node = data
    try:
        for k in keys[:-1]:
            node = node[k]
        node[keys[-1]] = value  # an unknown leaf is caught by scenario validation
    except (KeyError, IndexError, TypeError):
        raise BatchError(f"{source}: {dotted}: no such field in the base scenario") from None


def _seed_of(master: int, index: int) -> int:
    """Run seed derived from the master seed (independent streams, stable across versions)."""
    return int(np.random.SeedSequence([master, index]).generate_state(1, dtype=np.uint64)[0] >> 1)


def load_batch(path: str | Path, out_dir: str | Path | None = None) -> tuple[str, list[RunSpec]]:
    """Expand a batch file into its runs (each scenario validated). Returns (name, runs)."""
    path = Path(path)
    src = str(path)
    try:
        cfg = tomllib.loads(path.read_text())
    except OSError as exc:
        raise BatchError(f"{src}: cannot read batch file ({exc.strerror})") from None
    except tomllib.TOMLDecodeError as exc:
        raise BatchError(f"{src}: not valid TOML: {exc}") from None
    unknown = set(cfg) - {"base", "name", "duration", "sweep", "monte_carlo"}
    if unknown:
        raise BatchError(f"{src}: {sorted(unknown)[0]}: unknown key")
    if "base" not in cfg:
        raise BatchError(f"{src}: base: missing required field")
    base_path = (path.parent / cfg["base"]).resolve()
    try:
        base = tomllib.loads(base_path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise BatchError(f"{src}: base: cannot load {base_path}: {exc}") from None
    name = cfg.get("name", path.stem)
    duration = to_si(cfg["duration"], "time") if "duration" in cfg else None
    out = Path(out_dir) if out_dir else Path("logs") / "batch" / name

    sweep: dict = cfg.get("sweep", {})
    for k, v in sweep.items():
        if not isinstance(v, list) or not v:
            raise BatchError(f"{src}: sweep.{k}: must be a non-empty list of values")
    grid = [dict(zip(sweep, combo, strict=False)) for combo in itertools.product(*sweep.values())] or [{}]

    mc = cfg.get("monte_carlo", {})
    unknown = set(mc) - {"runs", "seed", "uniform", "normal"}
    if unknown:
        raise BatchError(f"{src}: monte_carlo.{sorted(unknown)[0]}: unknown key")
    n_mc = int(mc.get("runs", 1))
    master = int(mc.get("seed", base.get("seed", 0)))
    rng = np.random.default_rng(master)

    runs: list[RunSpec] = []
    index = 0
    for point in grid:
        for _draw in range(n_mc):
            params = dict(point)
            for key, (lo, hi) in mc.get("uniform", {}).items():
                params[key] = float(rng.uniform(lo, hi))
            for key, (mean, std) in mc.get("normal", {}).items():
                params[key] = float(rng.normal(mean, std))
            scen = copy.deepcopy(base)
            for key, value in params.items():
                _set_path(scen, key, value, src)
            seed = _seed_of(master, index)
            scen["seed"] = seed
            run_id = f"{name}_{index:04d}"
            scen["name"] = run_id
            try:
                parse_scenario(scen, f"{src} run {run_id}")
            except ScenarioError as exc:
                raise BatchError(str(exc)) from None
            runs.append(
                RunSpec(
                    run_id,
                    scen,
                    duration,
                    str(out / "runs" / f"{run_id}.mcap"),
                    str(out / "runs" / f"{run_id}.json"),
                    {"seed": seed, **params},
                )
            )
            index += 1
    return name, runs


def run_one(spec: RunSpec) -> dict:
    """Fly one run (in a worker); returns its result row. Never raises for a failed run."""
    from sim.runner import RunFailed, run_scenario

    scenario = parse_scenario(spec.scenario, spec.run_id)
    row = {"run_id": spec.run_id, **{f"param.{k}": v for k, v in spec.params.items()}}
    try:
        r = run_scenario(scenario, spec.log_path, duration=spec.duration, scenario_text=tomli_w.dumps(spec.scenario))
        row.update(status=r.status, sim_time_s=r.sim_time_s, error="")
        metrics = r.metrics
    except RunFailed as exc:
        r = exc.result
        row.update(status="failed", sim_time_s=r.sim_time_s, error=r.error or "")
        metrics = r.metrics
    row.update({f"metric.{k}": v for k, v in flatten(metrics).items()})
    tmp = Path(spec.result_path + ".tmp")
    tmp.parent.mkdir(parents=True, exist_ok=True)
    tmp.write_text(json.dumps(row, sort_keys=True))
    os.replace(tmp, spec.result_path)
    return row


def run_batch(
    runs: list[RunSpec],
    out_dir: str | Path,
    executor: Executor | None = None,
    workers: int = 1,
    progress: Callable[[int, int, dict], None] | None = None,
    resume: bool = True,
) -> list[dict]:
    """Run every spec (skipping finished ones when ``resume``), write ``results.csv``, return rows
    in run order."""
    out = Path(out_dir)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    rows: dict[str, dict] = {}
    todo = []
    for spec in runs:
        done = Path(spec.result_path)
        if resume and done.is_file():
            rows[spec.run_id] = json.loads(done.read_text())
        else:
            todo.append(spec)
    own = executor is None
    ex = executor or ProcessPoolExecutor(max_workers=workers)
    try:
        futures = {ex.submit(run_one, spec): spec for spec in todo}
        for k, fut in enumerate(as_completed(futures), 1):
            spec = futures[fut]
            try:
                row = fut.result()
            except Exception as exc:  # noqa: BLE001 (the worker itself died, of anything: not a failed flight)
                row = {"run_id": spec.run_id, "status": "failed", "error": f"worker: {exc}"}
            rows[spec.run_id] = row
            if progress:
                progress(k, len(todo), row)
    finally:
        if own:
            ex.shutdown(cancel_futures=True)
    ordered = [rows[s.run_id] for s in runs]
    write_csv(out / "results.csv", ordered)
    return ordered


def write_csv(path: Path, rows: Iterable[dict]) -> None:
    rows = list(rows)
    columns = sorted({k for r in rows for k in r}, key=lambda c: (c != "run_id", c != "status", c))
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=columns)
        w.writeheader()
        w.writerows(rows)
