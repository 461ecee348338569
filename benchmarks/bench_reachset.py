"""Per-decision cost of the reach-set planner at the shipped scale, against the previous intruder
rating measured in the same run.

The planners are built exactly as the simulator builds them, from the shipped scenario files
(``scenarios/reachset/s7_head_on.toml``: the reach-set planner with its 5 m movements and 4.55 m
intruder margin; ``scenarios/rules/s10_head_on.toml``: the same planner under the rules of the
air), through the project's scenario loader and planner factory. One decision = one
``planner.plan`` call at a due frame (threat collection, situation assessment, the grid runs of
the mode, path selection, plan vertices). Scenes (NED, around the first vehicle at its start):
0, 1, 5 and 20 quadrotor-sized intruders converging on the grid; one HAPS 17 km above
(cannot reach the grid within its horizon); one quadrotor 2 km away (idem).

``baseline`` is the previous intruder rating (point lattices at a fixed 0.2 m spacing, every
intruder rated however far), kept here only (:class:`LatticeIntruderModel`) and swapped into
the assessor for the baseline rows; ``current`` is the package's code. Reports median and p95
wall time per decision [ms] on one core, the ratio baseline / current, and the cost an
unreachable intruder adds to the 0-intruder scene. Writes benchmarks/results/bench_reachset.json.

    python benchmarks/bench_reachset.py [--repeat 30] [--paths baseline,current]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from aircraft.registry import get_airframe  # noqa: E402
from avoidance.reachset.threats.intruders import (  # noqa: E402
    IntruderModel,
    _perpendicular_basis,
    _time_rate,
)
from sim.core.plan import Planner, Threats  # noqa: E402
from sim.core.state import VehicleState  # noqa: E402
from sim.core.threats import IntruderTrack  # noqa: E402
from sim.planner_registry import make_planner  # noqa: E402
from sim.scenario import load_scenario  # noqa: E402
from sim.vehicle_setup import mission_from_config  # noqa: E402

SCENARIOS = {"reachset": "scenarios/reachset/s7_head_on.toml", "rules": "scenarios/rules/s10_head_on.toml"}
TARGETS_MS = {"5_intruders": 20.0, "20_intruders": 80.0}
ADDED_TARGET_MS = 1.0


# --- the previous intruder rating (baseline only) ------------------------------------------------


@lru_cache(maxsize=8)
def _unit_ball(step: float) -> np.ndarray:
    u = np.arange(-1.0, 1.0 + 1e-9, step)
    p = np.stack(np.meshgrid(u, u, u, indexing="ij"), axis=-1).reshape(-1, 3)
    return p[np.einsum("ij,ij->i", p, p) <= 1.0 + 1e-9]


class LatticeIntruderModel:
    """The line + body + time rating before issue #16: line samples every 0.2 m, a 0.2 m disc
    lattice ⊥ v swept along the line plus ball lattices at both ends, binned per cell."""

    spacing = 0.2

    def __init__(self, model: IntruderModel):
        self.grid, self.cfg, self.u_e, self.u_l = model.grid, model.cfg, model.u_e, model.u_l
        self.horizon = float(self.u_l.max(initial=0.0)) + self.cfg.time_error

    def _bin(self, pts: np.ndarray, toa: np.ndarray):
        cells = self.grid.cell_index(pts)
        ok = cells >= 0
        c, t = cells[ok], toa[ok]
        hit = np.bincount(c, minlength=self.grid.n_cells)
        i_e = np.full(self.grid.n_cells, np.inf)
        i_l = np.full(self.grid.n_cells, -np.inf)
        np.minimum.at(i_e, c, t)
        np.maximum.at(i_l, c, t)
        return hit, i_e, i_l

    def _rate(self, hit: np.ndarray, i_e: np.ndarray, i_l: np.ndarray, speed: float) -> np.ndarray:
        tol = self.cfg.time_error + (self.grid.steps[0] / speed if speed > 0 else 0.0)
        return (hit > 0) * _time_rate(i_e, i_l, self.u_e - tol, self.u_l + tol)

    def rating(self, x_s: np.ndarray, v: np.ndarray, radius: float) -> np.ndarray:
        speed = float(np.linalg.norm(v))
        n_t = max(3, int(np.ceil(speed * self.horizon / self.spacing)) + 1)
        tau = np.linspace(0.0, self.horizon, n_t)
        line = x_s + tau[:, None] * v
        out = self._rate(*self._bin(line, tau), speed)
        ball = _unit_ball(min(1.0, self.spacing / max(radius, 1e-9))) * radius
        if speed == 0.0:
            pts, toa = line[:1] + ball, np.zeros(len(ball))
        else:
            e2, e3 = _perpendicular_basis(v / speed)
            disc = ball[np.abs(ball[:, 2]) < 1e-9][:, :2]
            sweep = line[:, None, :] + disc[None, :, 0:1] * e2 + disc[None, :, 1:2] * e3
            pts = np.concatenate([sweep.reshape(-1, 3), line[0] + ball, line[-1] + ball])
            toa = np.concatenate([np.repeat(tau, len(disc)), np.full(len(ball), tau[0]), np.full(len(ball), tau[-1])])
        return np.maximum(out, self._rate(*self._bin(pts, toa), speed))


def lattice_ratings(model: IntruderModel, motion: np.ndarray) -> np.ndarray:
    """``IntruderModel.ratings`` as it was: every intruder rated by the lattices."""
    old = LatticeIntruderModel(model)
    out = np.zeros((len(motion), model.grid.n_cells))
    for n, m in enumerate(motion):
        out[n] = old.rating(m[:3], m[3:6], float(m[6]))
    return out


@contextmanager
def code_path(name: str) -> Iterator[None]:
    """``baseline``: the lattice rating swapped into the assessor; ``current``: the package's."""
    if name == "current":
        yield
        return
    saved = IntruderModel.ratings
    IntruderModel.ratings = lattice_ratings
    try:
        yield
    finally:
        IntruderModel.ratings = saved


# --- scenes ----------------------------------------------------------------------------------------


def converging(n: int, here: np.ndarray, t: float) -> list[IntruderTrack]:
    """``n`` quadrotors (0.45 m body, 5 m/s) 25-45 m ahead of a vehicle at ``here`` flying east,
    spread over ±60° and ±10 m of height, each heading for a point near the vehicle (NED)."""
    out = []
    for k in range(n):
        ang = np.radians(-60.0 + 120.0 * k / max(n - 1, 1))
        rng = 25.0 + 20.0 * (k % 3) / 2.0
        rel = np.array([rng * np.sin(ang), rng * np.cos(ang), 10.0 * ((k % 5) / 2.0 - 1.0)])
        aim = np.array([0.0, 10.0, 0.0]) - rel
        out.append(IntruderTrack(f"q{k}", t, here + rel, 5.0 * aim / np.linalg.norm(aim), 0.45))
    return out


def scenes(here: np.ndarray) -> dict[str, Callable[[float], Threats]]:
    haps = np.array([0.0, 0.0, -17000.0])
    far = np.array([2000.0, 0.0, 0.0])
    return {
        "0_intruders": lambda t: Threats(),
        "1_intruder": lambda t: Threats(intruders=converging(1, here, t)),
        "5_intruders": lambda t: Threats(intruders=converging(5, here, t)),
        "20_intruders": lambda t: Threats(intruders=converging(20, here, t)),
        "haps_17km_above": lambda t: Threats(
            intruders=[IntruderTrack("haps", t, here + haps, np.array([0.0, 26.0, 0.0]), 12.5, cooperative=True)]
        ),
        "quad_2km_away": lambda t: Threats(
            intruders=[IntruderTrack("far", t, here + far, np.array([-5.0, 0.0, 0.0]), 0.45)]
        ),
    }


def shipped_planner(path: str) -> tuple[Planner, VehicleState, float]:
    """The first vehicle's planner of a shipped scenario file, its start state (NED, level, at
    cruise speed along the first leg) and its decision period [s]."""
    scenario, _ = load_scenario(ROOT / path)
    cfg = scenario.vehicle[0]
    mission = mission_from_config(cfg, scenario.origin_point)
    kind = get_airframe(cfg.aircraft).kind
    planner = make_planner(cfg.planner.type, mission, kind, cfg.planner.options)
    leg = mission.waypoints[0] - mission.start
    vel = mission.cruise_speed * leg / np.linalg.norm(leg)
    yaw = float(np.arctan2(vel[1], vel[0]))
    state = VehicleState(0.0, mission.start.copy(), vel, np.array([0.0, 0.0, yaw]), np.zeros(3), 0.0, 0.0, 0.0)
    return planner, state, 1.0 / cfg.planner.rate_hz


def decision_times(planner: Planner, state: VehicleState, period: float, scene, repeat: int) -> np.ndarray:
    """Wall time [s] of ``repeat`` due decisions (after one warm-up), one ``period`` apart, the
    vehicle held at its start with its buffer cleared before each (every decision assesses the
    same scene)."""
    control = planner.control
    out = []
    t = planner.last_decision.t_grid if planner.last_decision is not None else 0.0
    for k in range(repeat + 1):
        t += period
        threats = scene(t)
        est = VehicleState(t, state.pos_ned, state.vel_ned, state.euler, state.rates_body, 0.0, 0.0, 0.0)
        control.buffer = []
        t0 = time.perf_counter()
        planner.plan(est, threats, t)
        if k:
            out.append(time.perf_counter() - t0)
    return np.array(out)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=30)
    ap.add_argument("--paths", default="baseline,current")
    ap.add_argument("--scenarios", default=",".join(SCENARIOS))
    ap.add_argument("--scenes", default="", help="comma-separated subset of the scenes (default: all)")
    args = ap.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    results: dict[str, dict] = {}
    for family in args.scenarios.split(","):
        for path in args.paths.split(","):
            planner, state, period = shipped_planner(SCENARIOS[family])
            all_scenes = scenes(state.pos_ned)
            chosen = args.scenes.split(",") if args.scenes else list(all_scenes)
            rows = {}
            with code_path(path):
                for name in chosen:
                    times = 1e3 * decision_times(planner, state, period, all_scenes[name], args.repeat)
                    rows[name] = {
                        "median_ms": round(float(np.median(times)), 3),
                        "p95_ms": round(float(np.percentile(times, 95)), 3),
                        "mode": planner.last_decision.mode.value,
                        "status": planner.last_decision.status,
                    }
            results[f"{family}/{path}"] = rows
    report: dict = {
        "benchmark": "reachset_decision",
        "scenarios": {f: SCENARIOS[f] for f in args.scenarios.split(",")},
        "repeat": args.repeat,
        "python": platform.python_version(),
        "machine": platform.machine(),
        "results": results,
        "checks": {},
    }
    for family in args.scenarios.split(","):
        cur = results.get(f"{family}/current", {})
        base = results.get(f"{family}/baseline", {})
        for name, row in cur.items():
            if name in base:
                row["speedup_vs_baseline"] = round(base[name]["median_ms"] / row["median_ms"], 1)
        checks = {}
        for name, target in TARGETS_MS.items():
            if name in cur:
                checks[f"{name}_median_le_{target:g}ms"] = cur[name]["median_ms"] <= target
        if "0_intruders" in cur:
            for name in ("haps_17km_above", "quad_2km_away"):
                if name in cur:
                    added = cur[name]["median_ms"] - cur["0_intruders"]["median_ms"]
                    cur[name]["added_ms"] = round(added, 3)
                    checks[f"{name}_adds_le_{ADDED_TARGET_MS:g}ms"] = added <= ADDED_TARGET_MS
        report["checks"][family] = checks
    out = ROOT / "benchmarks" / "results" / "bench_reachset.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(report, indent=2))
    for key, rows in results.items():
        print(f"[{key}]")
        for name, r in rows.items():
            extra = "".join(f"  {k} {r[k]}" for k in ("speedup_vs_baseline", "added_ms") if k in r)
            print(f"  {name:16s} median {r['median_ms']:8.2f} ms  p95 {r['p95_ms']:8.2f} ms  {r['mode']}{extra}")
    print(json.dumps(report["checks"], indent=1))
    print(f"-> {out}")


if __name__ == "__main__":
    main()
