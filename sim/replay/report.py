"""A run report: Markdown with plots (map, altitude, airspeed, bank, separation), the decision
trail of the rules of the air and the UTM authority (:mod:`sim.replay.decision_trail`), and JSON
metrics.

The log is read once, message by message (:mod:`sim.replay.log_stream`); plots show the series
thinned to at most 8192 samples each (:mod:`sim.replay.thinned`), so memory does not grow with
the log's length. Plots use matplotlib's Agg backend (files only, no screen needed).
"""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sim.mcap_read import LogInfo, log_content, read_attached_scenario, read_info
from sim.replay.decision_trail import trail_markdown
from sim.replay.log_stream import log_vehicles, stream_metrics
from sim.replay.metrics import MetricsWorld, flatten
from sim.replay.runlog import RunLog
from sim.replay.thinned import Thinned
from sim.replay.trace import VehicleTrace


def load_world(path: Path, info: LogInfo) -> MetricsWorld:
    """Obstacles, geofences, thresholds and planned duration of the run, from its attached
    scenario and its ``run`` metadata."""
    scenario = read_attached_scenario(path)
    duration = info.metadata.get("run", {}).get("duration_s")
    if scenario is None:
        return MetricsWorld()
    return MetricsWorld.from_scenario(scenario, None if duration is None else float(duration))


def log_metrics(log: RunLog | str | Path) -> dict:
    """The run's metrics recomputed from its log by streaming (LogReadError if its messages are
    not cosim's)."""
    path = log.path if isinstance(log, RunLog) else Path(log)
    info = read_info(path)
    with log_content(path):
        return stream_metrics(path, info, load_world(path, info))


class _PlotData:
    """What the plots need, gathered while the metrics stream: each vehicle's series and each
    pair's separation thinned (:class:`Thinned`), each vehicle's first plan, the ``/log`` events."""

    def __init__(self, vehicles: list[str]) -> None:
        self.vehicles = {v: Thinned() for v in vehicles}
        self.pairs: dict[tuple[str, str], Thinned] = {}
        self.first_plan: dict[str, np.ndarray] = {}
        self.events: list[tuple[float, str]] = []

    def chunk(self, tr: VehicleTrace) -> None:
        nan = np.full(len(tr.t), np.nan)
        sp = tr.setpoint
        speed = nan if tr.truth_vel_ned is None else np.linalg.norm(tr.truth_vel_ned, axis=1)
        self.vehicles[tr.name].add(
            t=tr.t,
            north=tr.pos_ned[:, 0],
            east=tr.pos_ned[:, 1],
            alt=tr.alt_msl_m,
            alt_demand=sp["altitude_m"],
            tas=tr.tas_mps,
            tas_demand=sp.get("tas_mps", nan),
            speed=speed,
            bank=tr.euler[:, 0],
            cross=tr.true_cross_track(),
        )

    def pair(self, a: str, b: str, t: np.ndarray, rel_ned: np.ndarray) -> None:
        self.pairs.setdefault((a, b), Thinned()).add(t=t, dist=np.linalg.norm(rel_ned, axis=1))

    def message(self, topic: str, t: float, msg) -> None:
        if topic == "/log":
            self.events.append((t, msg.message))
        elif topic.endswith("/plan"):
            self.first_plan.setdefault(topic.split("/")[1], np.asarray(msg["positions"], float))


def _map_plot(data: _PlotData, path: Path) -> None:
    fig, ax = plt.subplots(figsize=(7, 7))
    for name, tr in data.vehicles.items():
        ax.plot(tr["east"] / 1e3, tr["north"] / 1e3, label=name)
        first = data.first_plan.get(name)
        if first is not None:
            ax.plot(first[:, 1] / 1e3, first[:, 0] / 1e3, "k--", lw=0.8, alpha=0.6)
        ax.plot(tr["east"][0] / 1e3, tr["north"][0] / 1e3, "o", color="k", ms=4)
    ax.set_xlabel("east [km]")
    ax.set_ylabel("north [km]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend()
    ax.set_title("ground track (dashed: first plan)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _time_plots(name: str, tr: Thinned, path: Path) -> None:
    fig, axes = plt.subplots(3, 1, figsize=(9, 7.5), sharex=True)
    tm = tr["t"] / 60.0
    axes[0].plot(tm, tr["alt"], label="altitude")
    axes[0].plot(tm, tr["alt_demand"], "--", label="demand")
    axes[0].set_ylabel("altitude MSL [m]")
    if np.isfinite(tr["tas_demand"]).any():
        axes[1].plot(tm, tr["tas"], label="TAS")
        axes[1].plot(tm, tr["tas_demand"], "--", label="demand")
        axes[1].set_ylabel("airspeed [m/s]")
    else:
        axes[1].plot(tm, tr["speed"], label="ground speed (3-D)")
        axes[1].set_ylabel("speed [m/s]")
    axes[2].plot(tm, np.degrees(tr["bank"]), label="bank")
    axes[2].plot(tm, tr["cross"] / 10.0, label="true cross-track / 10 [m]", alpha=0.7)
    axes[2].set_ylabel("bank [deg]")
    axes[2].set_xlabel("sim time [min]")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    axes[0].set_title(f"{name}: holding and tracking")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _separation_plot(data: _PlotData, path: Path) -> bool:
    if not data.pairs:
        return False
    fig, ax = plt.subplots(figsize=(9, 3.5))
    for (a, b), sep in data.pairs.items():
        ax.plot(sep["t"] / 60.0, sep["dist"], label=f"{a}-{b}")
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
    """Write ``report.md``, ``metrics.json`` and PNG plots into ``out_dir``, reading the log by
    streaming; returns (report path, metrics)."""
    path = Path(log_path)
    info = read_info(path)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    with log_content(path):
        return _write_report(path, info, out)


def _write_report(path: Path, info: LogInfo, out: Path) -> tuple[Path, dict]:
    vehicles = log_vehicles(info)
    data = _PlotData(vehicles)
    plans = tuple(f"/{v}/plan" for v in vehicles)
    metrics = stream_metrics(
        path, info, load_world(path, info), data.chunk, data.pair, extra=plans, on_message=data.message
    )
    (out / "metrics.json").write_text(json.dumps(metrics, indent=2, sort_keys=True))
    _map_plot(data, out / "map.png")
    for name, tr in data.vehicles.items():
        _time_plots(name, tr, out / f"{name}_timeseries.png")
    has_sep = _separation_plot(data, out / "separation.png")
    run = info.metadata.get("run", {})
    res = info.metadata.get("result", {})
    lines = [
        f"# Run report: {run.get('scenario', path.stem)}",
        "",
        f"- log: `{path}`",
        f"- seed: {run.get('seed', '?')}; result: **{res.get('status', '?')}**; sim time {info.end_s:.1f} s",
        f"- versions: cosim {run.get('cosim_version', '?')}, jsbsim {run.get('jsbsim_version', '?')}",
        *(
            []
            if info.finished
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
    for name in data.vehicles:
        lines += [f"## {name}", "", f"![{name}]({name}_timeseries.png)", ""]
    if has_sep:
        lines += ["## Separation", "", "![separation](separation.png)", ""]
    lines += trail_markdown(path, info)
    if data.events:
        lines += ["## Events", "", "| sim time [s] | event |", "|---|---|"]
        lines += [f"| {t:.1f} | {text} |" for t, text in data.events]
    report = out / "report.md"
    report.write_text("\n".join(lines) + "\n")
    return report, metrics


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return "–" if v is None else str(v)
