"""The result tables of docs/mptp.md, computed from the code (deterministic numbers only: lengths,
times, expansions, distances; wall-clock timings are benchmarks/bench_mptp.py's).

    python -m sim.testbeds.mptp_tables [--closed-loop matched|1] [--write]

prints the tables as Markdown; ``--write`` replaces each one in docs/mptp.md between its markers
``<!-- generated: NAME -->`` and ``<!-- end generated -->``. Without ``--closed-loop`` the
open-loop tables (thesis scenarios replanned open loop, heuristics at a raised cap); with it the
thesis scenarios flown by the JSBSim HAPS on its EKF at that space scale.
"""

from __future__ import annotations

import argparse
import re
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from guidance.mptp.search import plan_trajectory
from guidance.mptp.timeline import ObstacleTimeline
from sim.testbeds import mptp_thesis as S
from sim.testbeds.mptp_openloop import run_open_loop

DOC = Path(__file__).resolve().parents[2] / "docs" / "mptp.md"
HEURISTICS_CAP = 2000  # expansions for the heuristics comparison (the planner's default is 120)
THESIS = (S.scenario_1, S.scenario_2, S.holding_scenario, S.moving_goal_scenario)


def openloop_row(make: Callable[[], S.Scenario]) -> dict:
    """One thesis scenario replanned open loop until arrival (the planner's default cap)."""
    sc = make()
    run = run_open_loop(sc)
    first = run.plans[0].diagnostics
    return {
        "scenario": sc.name,
        "plans": len(run.plans),
        "first_tl_km": float(first.get("path_length_m", float("nan"))) / 1000,
        "first_exst": int(first.get("expanded", 0)),
        "flown_km": run.length_m / 1000,
        "arrival_min": run.arrived_s / 60,
        "non_ok": sum(p.status.value != "ok" for p in run.plans),
    }


def heuristics_row(make: Callable[..., S.Scenario], heuristic: str, turning: str, cap: int = HEURISTICS_CAP) -> dict:
    """The first search of a thesis scenario with one heuristic and turning mode."""
    sc = make(heuristic, turning)
    cfg = sc.cfg.with_(max_expansions=cap)
    tl = ObstacleTimeline(sc.storms.nowcast(0.0), cfg, 2 * cfg.horizon_s)
    tr = plan_trajectory(tl, sc.start, 0.0, sc.course, sc.goal, cfg)
    return {
        "scenario": sc.name,
        "turning": turning,
        "heuristic": heuristic,
        "status": tr.status,
        "exst": tr.expanded,
        "trst": max(len(tr.positions) - 1, 0),
        "tl_km": tr.length_m / 1000 if tr.status == "ok" else float("nan"),
        "search_s": tr.runtime_s,
    }


def closed_loop_row(make: Callable[[], S.Scenario], scale: str) -> dict:
    """One thesis scenario flown by the JSBSim HAPS (space scale ``scale``: "matched" or a
    number); numbers read from the MCAP log."""
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


def openloop_table(rows: list[dict]) -> str:
    out = [
        "| scenario | plans | first plan [km] | first plan EXST | flown [km] | arrival [min] | non-OK plans |",
        "|---|---|---|---|---|---|---|",
    ]
    out += [
        f"| {r['scenario']} | {r['plans']} | {_num(r['first_tl_km'])} | {r['first_exst']} | {r['flown_km']:.1f} | "
        f"{_num(r['arrival_min'])} | {r['non_ok']} |"
        for r in rows
    ]
    return "\n".join(out)


def heuristics_table(rows: list[dict]) -> str:
    out = [
        "| scenario | turning | heuristic | status | EXST | TRST | TRST/EXST [%] | TL [km] |",
        "|---|---|---|---|---|---|---|---|",
    ]
    out += [
        f"| {r['scenario']} | {r['turning']} | {r['heuristic']} | {r['status']} | {r['exst']} | {r['trst']} | "
        f"{100 * r['trst'] / max(r['exst'], 1):.0f} | {_num(r['tl_km'])} |"
        for r in rows
    ]
    return "\n".join(out)


def closed_loop_table(rows: list[dict]) -> str:
    out = [
        "| scenario | scale (space, time) | arrival [min] | flown [km] | closest true storm [m] | inside [s] "
        "| non-OK plans | replans |",
        "|---|---|---|---|---|---|---|---|",
    ]
    out += [
        f"| {r['scenario']} | {r['space_scale']:.3g}, {r['time_scale']:.3g} | {_num(r['arrival_min'])} | "
        f"{r['flown_km']:.1f} | {r['storm_min_m']:.0f} | {r['inside_s']:.0f} | {', '.join(r['degraded']) or '-'} | "
        f"{r['replans']} |"
        for r in rows
    ]
    return "\n".join(out)


def generated(text: str, name: str) -> str:
    """The table named ``name`` in a document's text (between its markers)."""
    m = re.search(_pattern(name), text, re.S)
    if m is None:
        raise KeyError(f"no generated table {name!r} in the document")
    return m.group(2).strip("\n")


def replace_generated(text: str, name: str, table: str) -> str:
    generated(text, name)  # raises when the markers are missing
    return re.sub(_pattern(name), lambda m: f"{m.group(1)}\n{table}\n{m.group(3)}", text, count=1, flags=re.S)


def _pattern(name: str) -> str:
    return rf"(<!-- generated: {re.escape(name)} -->)(.*?)(<!-- end generated -->)"


def _num(x: float, fmt: str = ".1f") -> str:
    return "–" if not np.isfinite(x) else format(x, fmt)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--closed-loop", metavar="SCALE", help="the closed-loop HAPS table: 'matched' or a space scale")
    ap.add_argument("--write", action="store_true", help=f"replace the tables in {DOC}")
    args = ap.parse_args(argv)
    if args.closed_loop:
        name = f"closed-loop-{args.closed_loop}"
        tables = {name: closed_loop_table([closed_loop_row(make, args.closed_loop) for make in THESIS])}
    else:
        heur = [
            heuristics_row(make, h, turning)
            for make in (S.scenario_1, S.scenario_2)
            for turning in ("right", "both")
            for h in ("dijkstra", "edh", "ssph")
        ]
        tables = {
            "openloop": openloop_table([openloop_row(make) for make in THESIS]),
            "heuristics": heuristics_table(heur),
        }
    text = DOC.read_text()
    for name, table in tables.items():
        print(f"{name}:\n{table}\n")
        text = replace_generated(text, name, table)
    if args.write:
        DOC.write_text(text)


if __name__ == "__main__":
    main()
