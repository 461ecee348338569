"""MPTP replanning time per cycle, its growth with the storm vertex count, and the heuristics.

Measured in this run on this machine (one core, single-threaded numpy/GEOS):
- per cycle: the open-loop replans of the thesis's scenarios 1 and 2 (SSPH, bidirectional
  turning), split into weather processing (margins + interpolation, once per nowcast) and the
  trajectory search; target <= 1 s per replan;
- growth: the first replan of scenario 2 with every storm outline densified k times (same shapes,
  k x the vertices), with and without line smoothing; the ratio is against k = 1 in this run;
- heuristics: first-iteration explored / trajectory states (EXST, TRST), length and runtime of
  Dijkstra, EDH and SSPH with one-way and two-way turning (the thesis's Tables 6.2-6.16), with
  the expansion cap raised to ``mptp_tables.HEURISTICS_CAP`` so that each search can finish;
- closed loop (``--closed-loop SCALE``): the thesis's scenarios flown by the JSBSim HAPS on its
  EKF (guidance/mptp/haps_scenarios.py; SCALE "matched" or a space scale, 1 = full size):
  arrival, flown length, closest true storm, worst replan (wall clock, from the log);
- wind (``--wind N,E``): the per-cycle replans calm and in a steady wind (the planner in the
  air-mass frame), worst replan and its ratio to calm in the same run.

    python benchmarks/bench_mptp.py [--quick] [--closed-loop matched|1] [--wind N,E]

Writes benchmarks/results/mptp.json and prints Markdown tables.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import shapely

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from guidance.mptp.search import plan_trajectory  # noqa: E402
from guidance.mptp.timeline import ObstacleTimeline  # noqa: E402
from guidance.mptp.wind import WindForecast  # noqa: E402
from sim.core.threats import StormSnapshot  # noqa: E402
from sim.testbeds import mptp_thesis as S  # noqa: E402
from sim.testbeds.mptp_openloop import run_open_loop  # noqa: E402
from sim.testbeds.mptp_tables import closed_loop_row, heuristics_row  # noqa: E402


def per_cycle(make, wind: np.ndarray | None = None) -> dict:
    """Open-loop replans of one thesis scenario; with ``wind`` (north, east) [m/s] the aircraft
    flies in that true wind and the planner is given it as its forecast (air-mass frame)."""
    sc = make()
    forecast = None if wind is None else WindForecast.steady(*wind)
    run = run_open_loop(sc, wind_true=wind, wind_forecast=forecast)
    w = np.array([p.diagnostics.get("weather_s", 0.0) for p in run.plans])
    s = np.array([p.diagnostics.get("runtime_s", 0.0) for p in run.plans])
    return {
        "scenario": sc.name + ("" if wind is None else f" in wind {wind[0]:g}/{wind[1]:g} m/s"),
        "cycles": len(run.plans),
        "weather_mean_s": w.mean(),
        "search_mean_s": s.mean(),
        "total_mean_s": (w + s).mean(),
        "total_max_s": (w + s).max(),
        "flown_km": run.length_m / 1000,
        "arrival_min": run.arrived_s / 60,
        "partial": sum(p.status.value != "ok" for p in run.plans),
        "tl_km": [p.diagnostics.get("path_length_m", float("nan")) / 1000 for p in run.plans],
    }


def densified(snaps: list[StormSnapshot], k: int) -> list[StormSnapshot]:
    if k == 1:
        return snaps
    out = []
    for s in snaps:
        cells = []
        for c in s.cells:
            edge = np.median(np.linalg.norm(np.diff(np.asarray(c.exterior.coords), axis=0), axis=1))
            cells.append(shapely.segmentize(c, edge / k * 1.01))
        out.append(StormSnapshot(s.t, tuple(cells), s.velocities_ne))
    return out


def one_replan(sc, snaps, cfg, repeat: int) -> tuple[float, float, int]:
    best_w, best_s, exst = np.inf, np.inf, 0
    for _ in range(repeat):
        t0 = time.perf_counter()
        tl = ObstacleTimeline(snaps, cfg, 2 * cfg.horizon_s)
        w = time.perf_counter() - t0
        tr = plan_trajectory(tl, sc.start, 0.0, sc.course, sc.goal, cfg)
        best_w, best_s, exst = min(best_w, w), min(best_s, tr.runtime_s), tr.expanded
    return best_w, best_s, exst


def growth(multipliers, repeat: int) -> list[dict]:
    sc = S.scenario_2()
    base = sc.storms.nowcast(0.0)
    rows = []
    for smooth in (True, False):
        cfg = sc.cfg if smooth else sc.cfg.with_(simplify_tol_m=0.0)
        ref = None
        for k in multipliers:
            snaps = densified(base, k)
            nv = sum(len(c.exterior.coords) - 1 for c in snaps[0].cells)
            w, s, exst = one_replan(sc, snaps, cfg, repeat)
            ref = ref or (w + s)
            rows.append(
                {
                    "smoothing": smooth,
                    "multiplier": k,
                    "storm_vertices": nv,
                    "weather_s": w,
                    "search_s": s,
                    "total_s": w + s,
                    "ratio": (w + s) / ref,
                    "exst": exst,
                }
            )
    return rows


def heuristics() -> list[dict]:
    rows = [
        heuristics_row(make, h, turning)
        for make in (S.scenario_1, S.scenario_2)
        for turning in ("right", "both")
        for h in ("dijkstra", "edh", "ssph")
    ]
    return rows


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="fewer repeats and multipliers")
    ap.add_argument("--closed-loop", metavar="SCALE", help="only the closed-loop HAPS runs: 'matched' or a space scale")
    ap.add_argument(
        "--wind",
        metavar="N,E",
        help="only the per-cycle replans, calm and in this true (and forecast) wind [m/s], with the ratio of the "
        "worst replan in wind to calm in the same run",
    )
    args = ap.parse_args()
    out = ROOT / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    thesis = (S.scenario_1, S.scenario_2, S.holding_scenario, S.moving_goal_scenario)
    if args.closed_loop:
        rows = [closed_loop_row(make, args.closed_loop) for make in thesis]
        (out / f"mptp_closed_loop_{args.closed_loop}.json").write_text(json.dumps(rows, indent=1, default=float))
        print(
            "| scenario | space x | time x | status | arrival [min] | flown [km] | closest storm [m] | inside [s] "
            "| non-ok plans | replans | worst replan [s] | wall [s] |"
        )
        print("|---|---|---|---|---|---|---|---|---|---|---|---|")
        for r in rows:
            print(
                f"| {r['scenario']} | {r['space_scale']:.3g} | {r['time_scale']:.3g} | {r['status']} | "
                f"{r['arrival_min']:.1f} | {r['flown_km']:.1f} | {r['storm_min_m']:.0f} | {r['inside_s']:.0f} | "
                f"{', '.join(r['degraded']) or '-'} | {r['replans']} | {r['replan_max_s']:.2f} | {r['wall_s']:.0f} |"
            )
        return
    if args.wind:
        wind = np.array([float(x) for x in args.wind.split(",")])
        print(
            "| scenario | cycles | worst replan calm [s] | worst replan in wind [s] | ratio "
            "| arrival calm / wind [min] |"
        )
        print("|---|---|---|---|---|---|")
        for make in thesis:
            calm, windy = per_cycle(make), per_cycle(make, wind)
            print(
                f"| {calm['scenario']} | {calm['cycles']} / {windy['cycles']} | {calm['total_max_s']:.2f} | "
                f"{windy['total_max_s']:.2f} | {windy['total_max_s'] / calm['total_max_s']:.2f} | "
                f"{calm['arrival_min']:.1f} / {windy['arrival_min']:.1f} |"
            )
        return
    mult = (1, 3) if args.quick else (1, 2, 3, 4, 6)
    res = {
        "cycles": [per_cycle(make) for make in thesis],
        "growth": growth(mult, 1 if args.quick else 3),
        "heuristics": heuristics(),
    }
    (out / "mptp.json").write_text(json.dumps(res, indent=1, default=float))
    print(
        "| scenario | cycles | partial | weather mean [s] | search mean [s] | total mean [s] | total max [s] "
        "| flown [km] | arrival [min] |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for r in res["cycles"]:
        print(
            f"| {r['scenario']} | {r['cycles']} | {r['partial']} | {r['weather_mean_s']:.3f} | "
            f"{r['search_mean_s']:.3f} | {r['total_mean_s']:.3f} | {r['total_max_s']:.3f} | {r['flown_km']:.1f} | "
            f"{r['arrival_min']:.1f} |"
        )
    print("\n| smoothing | vertices x | storm vertices | weather [s] | search [s] | total [s] | ratio | EXST |")
    print("|---|---|---|---|---|---|---|---|")
    for r in res["growth"]:
        print(
            f"| {'on' if r['smoothing'] else 'off'} | {r['multiplier']} | {r['storm_vertices']} | "
            f"{r['weather_s']:.3f} | {r['search_s']:.3f} | {r['total_s']:.3f} | {r['ratio']:.2f} | {r['exst']} |"
        )
    print("\n| scenario | turning | heuristic | status | EXST | TRST | TRST/EXST [%] | TL [km] | search [s] |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in res["heuristics"]:
        print(
            f"| {r['scenario']} | {r['turning']} | {r['heuristic']} | {r['status']} | {r['exst']} | {r['trst']} | "
            f"{100 * r['trst'] / max(r['exst'], 1):.1f} | {r['tl_km']:.1f} | {r['search_s']:.2f} |"
        )


if __name__ == "__main__":
    main()
