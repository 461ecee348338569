"""The thesis's Monte-Carlo study of the heuristics (seed 002, 6.2, Table 6.17) on synthetic fields.

Frames/units: (north, east) [m] from the thesis's origin, times [s] from the nowcast issue,
courses [rad] from north (positive east) unless named ``_deg``.

A trial is a random start, goal and initial course in the mission area, drawn as the thesis
draws them: start and goal uniform in latitude/longitude, each at least ``BORDER_M`` inside the
border (the thesis: "not directly on a border") and outside the margin region's envelope of every
planning interval of the hour; the shortest static path between them around the margin region of the last nowcast
step (the largest coverage) 30-80 % of the aircraft's range in the hour (V_T 3600 s); the
initial course a random integer degree that does not point at the goal. The MPTP then plans once
from the start per heuristic with the study's parameters (Table 6.17: dt 50 s, V_T 80 m/s,
|dchi| 45 deg, eps 0.022 deg, bidirectional turning; margins 10 km at issue growing linearly to
20 km after one hour; at most ``MAX_EXPANSIONS`` = 100 expansions). A trial succeeds when the
search reaches the goal within the cap, as in the thesis.

Trials are grouped by field: ``run_field`` draws one storm field (``mptp_mc_fields``), builds its
obstacle timeline once and runs its trials, so the weather processing and the timeline's
envelope cache are shared, as the thesis ran all its trials on one nowcast.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import time
from collections.abc import Callable
from concurrent.futures import Executor, ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import shapely
from shapely.geometry import Polygon

from guidance.mptp.config import MptpConfig
from guidance.mptp.goal import GoalTrack
from guidance.mptp.heuristics import StaticPaths
from guidance.mptp.search import SharedWork, default_workspace, plan_trajectory
from guidance.mptp.statespace import FreeSpace
from guidance.mptp.timeline import ObstacleTimeline
from guidance.mptp.turning import bearing
from guidance.mptp.visibility import boundary_of
from sim.batch import _die_with_parent
from sim.geodesy import geodetic_to_ned
from sim.testbeds.mptp_mc_fields import FieldSpec, coverage, draw_cells, nowcast
from sim.testbeds.mptp_thesis import ORIGIN, mission_area

LAT, LON = (47.50, 50.00), (10.25, 14.00)  # the thesis's mission area [deg]
HORIZON_S = 3600.0
MARGIN_ISSUE_M, MARGIN_HORIZON_M = 10_000.0, 20_000.0  # 6.2: margins at t0 and at T_N
MAX_EXPANSIONS = 100  # 6.2: success = trajectory within 100 explored states
PATH_SHARE = (0.3, 0.8)  # shortest static path / (V_T T_N)
BORDER_M = 2_000.0  # start and goal at least this far inside the mission area [m]
HEURISTICS = ("edh", "ssph")


def study_config(heuristic: str = "ssph") -> MptpConfig:
    """The MPTP of Table 6.17: the thesis aircraft at dt 50 s, margins 10 -> 20 km (the
    probabilistic margin grows from 0 to 10 km over the hour, isotropic), cap 100."""
    k = math.sqrt(-2 * math.log(0.1))
    sigma = (MARGIN_HORIZON_M - MARGIN_ISSUE_M) / (k * HORIZON_S)
    return MptpConfig.thesis(
        mission_area=mission_area(),
        heuristic=heuristic,
        turning="both",
        dt_s=50.0,
        max_expansions=MAX_EXPANSIONS,
        probability=0.9,
        sigma_front_mps=sigma,
        sigma_back_mps=sigma,
        prob_margin_max_m=MARGIN_HORIZON_M - MARGIN_ISSUE_M,
        safety_single_m=(MARGIN_ISSUE_M,) * 3,
        safety_line_m=(MARGIN_ISSUE_M,) * 3,
    )


def study_field_spec() -> FieldSpec:
    """The field distribution calibrated to the thesis's coverage (docs/mptp.md)."""
    return FieldSpec(bounds=mission_area().bounds, n_cells=11, radius_m=(12_000.0, 28_000.0))


@dataclass(frozen=True, slots=True)
class Trial:
    field: int
    index: int
    start: tuple[float, float]  # (north, east) [m]
    goal: tuple[float, float]
    course_deg: int
    static_path_m: float


def _uniform_points(rng: np.random.Generator, n: int) -> np.ndarray:
    """n points uniform in the mission area's latitude/longitude interval, as (north, east) [m]."""
    lat, lon = rng.uniform(*LAT, n), rng.uniform(*LON, n)
    return geodetic_to_ned(lat, lon, np.zeros(n), ORIGIN)[:, :2]


def static_paths_at(tl: ObstacleTimeline, area: Polygon, goal: np.ndarray, t: float) -> StaticPaths:
    """Shortest static paths to ``goal`` around the margin region at time ``t`` [s] in ``area``."""
    free = area.difference(tl.shape_at(t))
    return StaticPaths(FreeSpace(goal, t, free, tl.shape_at(t), boundary_of(free), False), goal)


def draw_trials(tl: ObstacleTimeline, cfg: MptpConfig, field: int, n: int, seed: int) -> list[Trial]:
    """``n`` valid trials on timeline ``tl`` (see the module notes); seeded per (seed, field)."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, field]))
    area = cfg.mission_area
    assert area is not None
    inner = area.buffer(-BORDER_M)
    levels = np.arange(int(tl.interval(HORIZON_S)) + 1)
    envelopes = tl.envelopes(levels, levels + 1)
    last = tl.shape_at(HORIZON_S)
    free_last = area.difference(last)
    bound_last = boundary_of(free_last)
    rng_m = cfg.tas_mps * HORIZON_S
    out: list[Trial] = []
    tries = 0
    while len(out) < n:
        tries += 1
        if tries > 200 * n + 1000:
            raise RuntimeError(f"field {field}: only {len(out)} of {n} valid trials in {tries} draws")
        p = _uniform_points(rng, 2)
        ok = shapely.contains_xy(inner, p[:, 0], p[:, 1]).all()
        ok = ok and not any(shapely.intersects_xy(e, p[:, 0], p[:, 1]).any() for e in envelopes)
        if not ok:
            continue
        goal = p[1]
        paths = StaticPaths(FreeSpace(goal, HORIZON_S, free_last, last, bound_last, False), goal)
        d = float(paths.from_points(p[:1])[0])
        if not PATH_SHARE[0] * rng_m <= d <= PATH_SHARE[1] * rng_m:
            continue
        to_goal = round(math.degrees(float(bearing(p[0], goal)))) % 360
        course = int(rng.integers(0, 359, endpoint=True))
        if course == to_goal:
            continue
        out.append(
            Trial(field, len(out), (float(p[0, 0]), float(p[0, 1])), (float(goal[0]), float(goal[1])), course, d)
        )
    return out


def trial_workspace(trial: Trial, cfg: MptpConfig) -> Polygon:
    """The search workspace of ``trial``: start and goal padded, within the mission area."""
    return default_workspace(np.vstack([trial.start, trial.goal]), cfg, cfg.mission_area)


def trial_share(tl: ObstacleTimeline, trial: Trial, cfg: MptpConfig) -> SharedWork:
    """What the searches of ``trial`` with the study's heuristics share (search.SharedWork)."""
    return SharedWork(tl, GoalTrack.fixed(np.array(trial.goal)), cfg, trial_workspace(trial, cfg), 0.0)


def run_trial(tl: ObstacleTimeline, trial: Trial, cfg: MptpConfig, shared: SharedWork | None = None) -> dict:
    """Plan once from the trial's start; the row: success, EXST, TRST, length [m], arrival [s],
    ``runtime_s`` the CPU time of this process for the search [s] (less disturbed by other jobs
    on a loaded machine than ``wall_s``, the wall clock). With ``shared`` (trial_share, used by
    the trial's other heuristics too) both times include what the search reused from it, as
    when it builds everything itself. A search that raises is a failure with status
    "error: <exception>" and EXST 0."""
    p0, goal = np.array(trial.start), np.array(trial.goal)
    work = trial_workspace(trial, cfg)
    reused = (shared.reused_cpu_s, shared.reused_wall_s) if shared is not None else (0.0, 0.0)
    wall, cpu = time.perf_counter(), time.process_time()
    try:
        tr = plan_trajectory(
            tl,
            p0,
            0.0,
            math.radians(trial.course_deg),
            GoalTrack.fixed(goal),
            cfg,
            work,
            shared=shared,
        )
        failure = None
    except Exception as exc:  # noqa: BLE001 - a planner crash is this trial's outcome (a failure), kept in the row
        failure = f"error: {type(exc).__name__}: {exc}"
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    if shared is not None:
        cpu, wall = cpu + shared.reused_cpu_s - reused[0], wall + shared.reused_wall_s - reused[1]
    if failure is not None:
        return {**_failed(cfg.heuristic, cpu, wall), "status": failure}
    ok = tr.status == "ok"
    return {
        "heuristic": cfg.heuristic,
        "success": ok,
        "status": tr.status,
        "exst": tr.expanded,
        "trst": max(len(tr.positions) - 1, 0) if ok else 0,
        "length_m": tr.length_m if ok else float("nan"),
        "arrival_s": float(tr.times[-1]) if ok else float("nan"),
        "runtime_s": cpu,
        "wall_s": wall,
    }


def _failed(heuristic: str, cpu: float, wall: float) -> dict:
    nan = float("nan")
    return {
        "heuristic": heuristic,
        "success": False,
        "status": "error",
        "exst": 0,
        "trst": 0,
        "length_m": nan,
        "arrival_s": nan,
        "runtime_s": cpu,
        "wall_s": wall,
    }


def run_field(field: int, n_trials: int, seed: int, heuristics: tuple[str, ...] = HEURISTICS) -> list[dict]:
    """Draw field ``field``, its ``n_trials`` trials, and plan each with every heuristic (in
    alternating order per trial, so slow periods of a loaded machine hit both alike). One row
    per (trial, heuristic), with the trial's draw and the field's coverage."""
    spec = study_field_spec()
    cells = draw_cells(spec, field)
    cfgs = {h: study_config(h) for h in heuristics}
    base = cfgs[heuristics[0]]
    tl = ObstacleTimeline(nowcast(cells), base, 2 * HORIZON_S)
    trials = draw_trials(tl, base, field, n_trials, seed)
    area = base.mission_area
    cov = {
        "coverage_issue": coverage(cells, area, MARGIN_ISSUE_M, 0.0),
        "coverage_horizon": coverage(cells, area, MARGIN_HORIZON_M, HORIZON_S),
    }
    if any(c.with_(heuristic=base.heuristic) != base for c in cfgs.values()):
        raise ValueError("the study's configurations must differ only in the heuristic (their searches share work)")
    rows = []
    for tr in trials:
        order = heuristics if tr.index % 2 == 0 else heuristics[::-1]
        shared = trial_share(tl, tr, base)
        for h in order:
            row = {**asdict(tr), **cov, **run_trial(tl, tr, cfgs[h], shared)}
            row["start"], row["goal"] = list(tr.start), list(tr.goal)
            rows.append(row)
    return rows


def study_fingerprint() -> str:
    """Digest of the study's planner configurations and field distribution: a stored field is
    resumed only under the same ones (a change of either, e.g. the wait bound's time step,
    re-runs it)."""
    text = repr((study_field_spec(), *(study_config(h) for h in HEURISTICS)))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def field_path(out_dir: Path, field: int) -> Path:
    return out_dir / "fields" / f"field_{field:05d}.json"


def run_study(
    n_trials: int,
    per_field: int,
    seed: int,
    out_dir: str | Path,
    executor: Executor | None = None,
    workers: int = 2,
    progress: Callable[[int, int, int, list[dict]], None] | None = None,
) -> list[dict]:
    """Run ``n_trials`` trials in fields of ``per_field`` (fields 0, 1, ...) on ``executor``
    (default: a process pool of ``workers`` that dies with this process, as sim.batch's).
    Each finished field is stored as ``<out_dir>/fields/field_NNNNN.json`` (atomically) and a
    stored field of the same seed, size and study_fingerprint is not run again (resume; the
    directory may be anywhere, e.g. outside the checkout). Returns all rows."""
    out = Path(out_dir)
    (out / "fields").mkdir(parents=True, exist_ok=True)
    sizes = [min(per_field, n_trials - f * per_field) for f in range(math.ceil(n_trials / per_field))]
    rows: dict[int, list[dict]] = {}
    todo = []
    study = study_fingerprint()
    for f, n in enumerate(sizes):
        path = field_path(out, f)
        stored = json.loads(path.read_text()) if path.exists() else None
        if stored and (stored["seed"], stored["n_trials"], stored.get("study")) == (seed, n, study):
            rows[f] = stored["rows"]
        else:
            todo.append(f)
    own = executor is None
    ex = executor or ProcessPoolExecutor(max_workers=workers, initializer=_die_with_parent, initargs=(os.getpid(),))
    try:
        futures = {ex.submit(run_field, f, sizes[f], seed): f for f in todo}
        for k, fut in enumerate(as_completed(futures), 1):
            f = futures[fut]
            rows[f] = fut.result()
            path = field_path(out, f)
            tmp = path.with_suffix(".tmp")
            tmp.write_text(
                json.dumps({"seed": seed, "field": f, "n_trials": sizes[f], "study": study, "rows": rows[f]})
            )
            os.replace(tmp, path)
            if progress:
                progress(k, len(todo), f, rows[f])
    finally:
        if own:
            ex.shutdown(wait=False, cancel_futures=True)
    return [r for f in sorted(rows) for r in rows[f]]
