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
``<out>/runs/<run id>.json`` (written last, atomically) and all rows to ``<out>/results.csv``. A
run that raises is recorded as failed; the others go on. Resume: a run is skipped only when its
JSON holds a finished run (not ``interrupted``) of the same resolved scenario (``scenario_hash``:
SHA-256 of the validated scenario and the duration), so interrupted runs and runs whose scenario
the edited batch file changed are flown again. Runs go through any ``concurrent.futures.Executor``:
a process pool by default (its workers die with the batch process, Linux), or a Dask
``distributed`` cluster (``Client(address).get_executor()``).
"""

from __future__ import annotations

import contextlib
import copy
import csv
import hashlib
import itertools
import json
import os
import signal
from collections.abc import Callable, Iterable
from concurrent.futures import Executor, ProcessPoolExecutor, as_completed, wait
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import numpy as np
import tomli_w
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from sim.input_files import parse_toml, read_text
from sim.output_paths import path_under
from sim.replay.metrics import flatten
from sim.scenario import NAME_PATTERN, ScenarioError, describe_error, parse_scenario
from sim.units import quantity

MAX_RUNS = 100_000
UNFINISHED = "interrupted"  # a run status that resume flies again
_INTERRUPT_GRACE_S = 10.0  # how long an interrupted batch waits for its runs to close their logs


class BatchError(ValueError):
    """The batch file is invalid; the message names the file and the key."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class _MonteCarlo(_Strict):
    runs: Annotated[int, Field(ge=1, le=MAX_RUNS)] = 1
    seed: Annotated[int, Field(ge=0, lt=2**63)] | None = None
    uniform: dict[str, tuple[float, float]] = {}
    normal: dict[str, tuple[float, Annotated[float, Field(ge=0.0)]]] = {}


class BatchFile(_Strict):
    """The keys of a batch file (see the module docstring)."""

    base: str
    name: Annotated[str, Field(pattern=NAME_PATTERN, max_length=120)] | None = None
    duration: Annotated[float, quantity("time", 0.0, 30 * 86400.0, lo_open=True)] | None = None
    sweep: dict[str, Annotated[list, Field(min_length=1)]] = {}
    monte_carlo: _MonteCarlo = _MonteCarlo()


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


def _batch_file(path: Path) -> BatchFile:
    src = str(path)
    try:
        return BatchFile.model_validate(parse_toml(read_text(path, BatchError, "batch"), src, BatchError))
    except ValidationError as exc:
        errors = exc.errors(include_url=False)
        more = f" (+{len(errors) - 1} more)" if len(errors) > 1 else ""
        raise BatchError(f"{src}: {describe_error(errors[0])}{more}") from None


def load_batch(path: str | Path, out_dir: str | Path | None = None) -> tuple[str, list[RunSpec]]:
    """Expand a batch file into its runs (each scenario validated). Returns (name, runs)."""
    path = Path(path)
    src = str(path)
    cfg = _batch_file(path)
    base_path = (path.parent / cfg.base).resolve()
    try:
        base = parse_toml(read_text(base_path, BatchError, "base scenario"), str(base_path), BatchError)
    except BatchError as exc:
        raise BatchError(f"{src}: base: cannot load {exc}") from None
    name = cfg.name or path.stem
    try:
        out = Path(out_dir) if out_dir else path_under(Path("logs") / "batch", name)
    except ValueError as exc:
        raise BatchError(f"{src}: name: {exc} (name the batch with the name key)") from None
    duration = cfg.duration

    sweep = cfg.sweep
    grid = [dict(zip(sweep, combo, strict=True)) for combo in itertools.product(*sweep.values())] or [{}]
    mc = cfg.monte_carlo
    if len(grid) * mc.runs > MAX_RUNS:
        raise BatchError(f"{src}: {len(grid)} sweep points x {mc.runs} runs is more than {MAX_RUNS} runs")
    n_mc = mc.runs
    try:
        master = int(mc.seed if mc.seed is not None else base.get("seed", 0))
    except (TypeError, ValueError):
        raise BatchError(f"{src}: base: seed {base.get('seed')!r} is not an integer") from None
    rng = np.random.default_rng(master)

    runs: list[RunSpec] = []
    index = 0
    for point in grid:
        for _ in range(n_mc):
            params = dict(point)
            for key, (lo, hi) in mc.uniform.items():
                params[key] = float(rng.uniform(lo, hi))
            for key, (mean, std) in mc.normal.items():
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
                    str(path_under(out / "runs", f"{run_id}.mcap")),
                    str(path_under(out / "runs", f"{run_id}.json")),
                    {"seed": seed, **params},
                )
            )
            index += 1
    return name, runs


def scenario_hash(spec: RunSpec) -> str:
    """SHA-256 (hex) of the run's resolved scenario (validated, SI units) and duration: what
    decides whether a stored result still belongs to the run."""
    scenario = parse_scenario(spec.scenario, spec.run_id)
    doc = {"scenario": scenario.model_dump(mode="json"), "duration": spec.duration}
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


def _stored(spec: RunSpec, key: str) -> dict | None:
    """The stored row of a finished run of this very scenario, else None (fly it)."""
    try:
        row = json.loads(Path(spec.result_path).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(row, dict) or row.get("scenario_hash") != key or row.get("status") in (None, UNFINISHED):
        return None
    return row


def run_one(spec: RunSpec) -> dict:
    """Fly one run (in a worker); returns its result row. Never raises for a failed run. The row
    is stored as the run's JSON unless the run was interrupted."""
    from sim.runner import RunFailed, run_scenario

    scenario = parse_scenario(spec.scenario, spec.run_id)
    row = {
        "run_id": spec.run_id,
        "scenario_hash": scenario_hash(spec),
        **{f"param.{k}": v for k, v in spec.params.items()},
    }
    try:
        r = run_scenario(scenario, spec.log_path, duration=spec.duration, scenario_text=tomli_w.dumps(spec.scenario))
        row.update(status=r.status, sim_time_s=r.sim_time_s, error=r.error or "")  # a crash says what it hit
        metrics = r.metrics
    except RunFailed as exc:
        r = exc.result
        row.update(status="failed", sim_time_s=r.sim_time_s, error=r.error or "")
        metrics = r.metrics
    row.update({f"metric.{k}": v for k, v in flatten(metrics).items()})
    if row["status"] == UNFINISHED:
        return row
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
    """Run every spec (when ``resume``, skipping those with a stored finished result of the same
    scenario), write ``results.csv``, return rows in run order. Runs cut short by an interrupt
    come back with status ``interrupted`` and are flown again by the next resume."""
    out = Path(out_dir)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    rows: dict[str, dict] = {}
    todo = []
    for spec in runs:
        stored = _stored(spec, scenario_hash(spec)) if resume else None
        if stored is not None:
            rows[spec.run_id] = stored
        else:
            todo.append(spec)
    own = executor is None
    ex = executor or ProcessPoolExecutor(max_workers=workers, initializer=_die_with_parent, initargs=(os.getpid(),))
    futures: dict = {}
    interrupted = False
    try:
        futures = {ex.submit(run_one, spec): spec for spec in todo}
        for k, fut in enumerate(as_completed(futures), 1):
            spec = futures[fut]
            try:
                row = fut.result()
            except Exception as exc:  # noqa: BLE001 - the worker itself died (not a failed flight)
                row = {"run_id": spec.run_id, "status": "failed", "error": f"worker: {exc}"}
            rows[spec.run_id] = row
            if progress:
                progress(k, len(todo), row)
    except KeyboardInterrupt:
        # own workers get a SIGTERM too (``kill PID`` reaches this process alone; after a Ctrl-C
        # it is their second signal): a run flying stops at its next tick and closes its log,
        # finished runs are stored, and what is left after the grace is killed; every run cut
        # short is flown again on resume
        interrupted = True
        workers_now = list(getattr(ex, "_processes", {}).values()) if own else []
        for worker in workers_now:
            with contextlib.suppress(ProcessLookupError):
                os.kill(worker.pid, signal.SIGTERM)
        wait(futures, timeout=_INTERRUPT_GRACE_S)
        for worker in workers_now:
            worker.kill()
        raise
    finally:
        if own:
            ex.shutdown(wait=not interrupted, cancel_futures=True)
    ordered = [rows[s.run_id] for s in runs]
    write_csv(out / "results.csv", ordered)
    return ordered


def _die_with_parent(parent: int) -> None:
    """Pool worker initialiser: the kernel kills the worker when the batch process dies (any
    signal, SIGKILL included), so no orphan keeps flying queued runs next to a resume."""
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG (Linux)
    except (OSError, AttributeError):  # not Linux: no parent-death signal
        pass
    if os.getppid() != parent:  # the parent died before the prctl
        os._exit(1)


def write_csv(path: Path, rows: Iterable[dict]) -> None:
    rows = list(rows)
    columns = sorted({k for r in rows for k in r}, key=lambda c: (c != "run_id", c != "status", c))
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=columns)
        w.writeheader()
        w.writerows(rows)
