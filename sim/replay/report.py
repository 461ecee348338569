"""A run report: Markdown with plots (map, altitude, airspeed, bank, separation), the decision
trail of the rules of the air and the UTM authority (:mod:`sim.replay.decision_trail`), and JSON
metrics.

Plots use matplotlib's Agg backend (files only, no screen needed).
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sim.mcap_read import log_content, read_attached_scenario
from sim.replay.decision_trail import trail_markdown
from sim.replay.metrics import MetricsWorld, flatten, run_metrics
from sim.replay.pair_metrics import common_times
from sim.replay.runlog import RunLog
from sim.replay.trace import VehicleTrace


def load_traces(log: RunLog) -> list[VehicleTrace]:
    return [VehicleTrace.from_log(log, v) for v in log.vehicles]


def load_world(log: RunLog) -> MetricsWorld:
    """Obstacles, geofences, thresholds and planned duration of the run, from its attached
    scenario and its ``run`` metadata."""
    scenario = read_attached_scenario(log.path)
    duration = log.metadata.get("run", {}).get("duration_s")
    if scenario is None:
        return MetricsWorld()
    return MetricsWorld.from_scenario(scenario, None if duration is None else float(duration))


def log_metrics(log: RunLog) -> dict:
    """The run's metrics recomputed from its log (LogReadError if its messages are not cosim's)."""
    with log_content(log.path):
        return run_metrics(load_traces(log), load_world(log))


def _map_plot(traces: list[VehicleTrace], log: RunLog, path: Path) -> None:
    fig, ax = plt.subplots(figsize=(7, 7))
    for tr in traces:
        ax.plot(tr.pos_ned[:, 1] / 1e3, tr.pos_ned[:, 0] / 1e3, label=tr.name)
        plan_topic = f"/{tr.name}/plan"
        if log.has(plan_topic):
            first = np.asarray(log.topic(plan_topic).messages[0]["positions"])
            ax.plot(first[:, 1] / 1e3, first[:, 0] / 1e3, "k--", lw=0.8, alpha=0.6)
        ax.plot(tr.pos_ned[0, 1] / 1e3, tr.pos_ned[0, 0] / 1e3, "o", color="k", ms=4)
    ax.set_xlabel("east [km]")
    ax.set_ylabel("north [km]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend()
    ax.set_title("ground track (dashed: first plan)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _time_plots(tr: VehicleTrace, path: Path) -> None:
    fig, axes = plt.subplots(3, 1, figsize=(9, 7.5), sharex=True)
    tm = tr.t / 60.0
    axes[0].plot(tm, tr.alt_msl_m, label="altitude")
    axes[0].plot(tm, tr.setpoint["altitude_m"], "--", label="demand")
    axes[0].set_ylabel("altitude MSL [m]")
    if "tas_mps" in tr.setpoint:
        axes[1].plot(tm, tr.tas_mps, label="TAS")
        axes[1].plot(tm, tr.setpoint["tas_mps"], "--", label="demand")
        axes[1].set_ylabel("airspeed [m/s]")
    else:
        speed = np.linalg.norm(np.gradient(tr.pos_ned, tr.t, axis=0), axis=1) if len(tr.t) > 1 else tr.t * 0
        axes[1].plot(tm, speed, label="ground speed (3-D)")
        axes[1].set_ylabel("speed [m/s]")
    axes[2].plot(tm, np.degrees(tr.euler[:, 0]), label="bank")
    axes[2].plot(tm, tr.true_cross_track() / 10.0, label="true cross-track / 10 [m]", alpha=0.7)
    axes[2].set_ylabel("bank [deg]")
    axes[2].set_xlabel("sim time [min]")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    axes[0].set_title(f"{tr.name}: holding and tracking")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _separation_plot(traces: list[VehicleTrace], path: Path) -> bool:
    pairs = list(itertools.combinations(traces, 2))
    if not pairs:
        return False
    fig, ax = plt.subplots(figsize=(9, 3.5))
    for a, b in pairs:
        common, ia, ib = common_times(a, b)
        ax.plot(common / 60.0, np.linalg.norm(a.pos_ned[ia] - b.pos_ned[ib], axis=1), label=f"{a.name}-{b.name}")
    ax.set_yscale("log")
    ax.set_xlabel("sim time [min]")
    ax.set_ylabel("separation [m]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def write_report(log_path: str | Path, out_dir: str | Path) -> tuple[Path, dict]:
    """Write ``report.md``, ``metrics.json`` and PNG plots into ``out_dir``; returns
    (report path, metrics)."""
    log = RunLog(log_path)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    with log_content(log.path):
        return _write_report(log, out)


def _write_report(log: RunLog, out: Path) -> tuple[Path, dict]:
    traces = load_traces(log)
    metrics = run_metrics(traces, load_world(log))
    events = log.events()
    (out / "metrics.json").write_text(json.dumps(metrics, indent=2, sort_keys=True))
    _map_plot(traces, log, out / "map.png")
    for tr in traces:
        _time_plots(tr, out / f"{tr.name}_timeseries.png")
    has_sep = _separation_plot(traces, out / "separation.png")
    run = log.metadata.get("run", {})
    res = log.metadata.get("result", {})
    lines = [
        f"# Run report: {run.get('scenario', log.path.stem)}",
        "",
        f"- log: `{log.path}`",
        f"- seed: {run.get('seed', '?')}; result: **{res.get('status', '?')}**; sim time {log.info.end_s:.1f} s",
        f"- versions: cosim {run.get('cosim_version', '?')}, jsbsim {run.get('jsbsim_version', '?')}",
        *(
            []
            if log.info.finished
            else ["- **unfinished log** (its writer never closed it): read up to its last complete chunk"]
        ),
        "",
        "## Metrics",
        "",
        "| metric | value |",
        "|---|---|",
    ]
    for k, v in flatten(metrics).items():
        lines.append(f"| {k} | {_fmt(v)} |")
    lines += ["", "## Ground track", "", "![map](map.png)", ""]
    for tr in traces:
        lines += [f"## {tr.name}", "", f"![{tr.name}]({tr.name}_timeseries.png)", ""]
    if has_sep:
        lines += ["## Separation", "", "![separation](separation.png)", ""]
    lines += trail_markdown(log)
    if events:
        lines += ["## Events", "", "| sim time [s] | event |", "|---|---|"]
        lines += [f"| {t:.1f} | {text} |" for t, text in events]
    report = out / "report.md"
    report.write_text("\n".join(lines) + "\n")
    return report, metrics


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return "–" if v is None else str(v)
