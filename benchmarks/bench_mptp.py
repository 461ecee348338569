"""MPTP replanning time per cycle, its growth with the storm vertex count, and the heuristics.

Measured in this run on this machine (one core, single-threaded numpy/GEOS):
- per cycle: the open-loop replans of the thesis's scenarios 1 and 2 (SSPH, bidirectional
  turning), split into weather processing (margins + interpolation, once per nowcast) and the
  trajectory search; target <= 1 s per replan;
- growth: the first replan of scenario 2 with every storm outline densified k times (same shapes,
  k x the vertices), with and without line smoothing; the ratio is against k = 1 in this run;
- heuristics: first-iteration explored / trajectory states (EXST, TRST), length and runtime of
  Dijkstra, EDH and SSPH with one-way and two-way turning (the thesis's Tables 6.2-6.16), with
  the expansion cap raised to ``HEURISTICS_CAP`` so that each search can finish;
- closed loop (``--closed-loop SCALE``): the thesis's scenarios flown by the JSBSim HAPS on its
  EKF (guidance/mptp/haps_scenarios.py; SCALE "matched" or a space scale, 1 = full size):
  arrival, flown length, closest true storm, worst replan (wall clock, from the log).

    python benchmarks/bench_mptp.py [--quick] [--closed-loop matched|1]

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
from sim.core.threats import StormSnapshot  # noqa: E402
from sim.testbeds import mptp_thesis as S  # noqa: E402
from sim.testbeds.mptp_openloop import run_open_loop  # noqa: E402

HEURISTICS_CAP = 2000  # expansions for the heuristics comparison (the planner's default is 120)


def per_cycle(make) -> dict:
    sc = make()
    run = run_open_loop(sc)
    w = np.array([p.diagnostics.get("weather_s", 0.0) for p in run.plans])
    s = np.array([p.diagnostics.get("runtime_s", 0.0) for p in run.plans])
    return {
        "scenario": sc.name,
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


def closed_loop(make, scale: str) -> dict:
    """One thesis scenario flown by the JSBSim HAPS; numbers read from the MCAP log."""
    import tempfile

    import tomli_w

    from sim.replay.report import log_metrics
    from sim.replay.runlog import RunLog
    from sim.runner import run_scenario
    from sim.scenario import parse_scenario
    from sim.testbeds.mptp_haps import matched_scale, scenario_data, time_scale

    sc = make()
    s = matched_scale(sc) if scale == "matched" else float(scale)
    data = scenario_data(sc, s)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "run.mcap"
        result = run_scenario(parse_scenario(data, data["name"]), path, scenario_text=tomli_w.dumps(data))
        log = RunLog(path)
        haps = log_metrics(log)["vehicles"]["haps"]
        pos = log.topic("/haps/truth/state")["pos_ned"]
        plans = log.topic("/haps/plan").messages
        runtime = [
            m["diagnostics"].get("runtime_s", 0.0) + m["diagnostics"].get("weather_s", 0.0)
            for m in plans
            if "runtime_s" in m["diagnostics"]
        ]
        return {
            "scenario": sc.name,
            "space_scale": s,
            "time_scale": time_scale(sc, s),
            "status": result.status,
            "arrival_min": haps["mission"]["time_s"] / 60 if haps["mission"]["time_s"] else float("nan"),
            "flown_km": float(np.sum(np.linalg.norm(np.diff(pos[:, :2], axis=0), axis=1))) / 1000,
            "storm_min_m": haps["storms"]["min_distance_m"],
            "inside_s": haps["storms"]["time_inside_s"],
            "degraded": sorted({m["status"] for m in plans} - {"ok"}),
            "replans": len({m["t"] for m in plans}),
            "replan_max_s": max(runtime),
            "wall_s": result.wall_time_s,
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
    rows = []
    for make in (S.scenario_1, S.scenario_2):
        for turning in ("right", "both"):
            for h in ("dijkstra", "edh", "ssph"):
                sc = make(h, turning)
                cfg = sc.cfg.with_(max_expansions=HEURISTICS_CAP)
                tl = ObstacleTimeline(sc.storms.nowcast(0.0), cfg, 2 * cfg.horizon_s)
                tr = plan_trajectory(tl, sc.start, 0.0, sc.course, sc.goal, cfg)
                rows.append(
                    {
                        "scenario": sc.name,
                        "turning": turning,
                        "heuristic": h,
                        "status": tr.status,
                        "exst": tr.expanded,
                        "trst": max(len(tr.positions) - 1, 0),
                        "tl_km": tr.length_m / 1000 if tr.status == "ok" else float("nan"),
                        "search_s": tr.runtime_s,
                    }
                )
    return rows


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="fewer repeats and multipliers")
    ap.add_argument("--closed-loop", metavar="SCALE", help="only the closed-loop HAPS runs: 'matched' or a space scale")
    args = ap.parse_args()
    out = ROOT / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    thesis = (S.scenario_1, S.scenario_2, S.holding_scenario, S.moving_goal_scenario)
    if args.closed_loop:
        rows = [closed_loop(make, args.closed_loop) for make in thesis]
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
