"""``report.md`` of a campaign: summary and per-bin tables (one row or section per variant),
plots (matplotlib, Agg), and the encounters whose MCAPs were kept."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

if TYPE_CHECKING:
    from sim.encounters.campaign import Campaign

SUMMARY_KEYS = (
    "n",
    "nmac_mitigated",
    "nmac_unmitigated",
    "risk_ratio",
    "risk_ratio_ci95",
    "lowc_ratio",
    "induced_nmac",
    "completion_rate",
    "extra_path_m_mean",
    "extra_path_m_median",
    "min_separation_m_min",
    "min_separation_m_median",
)


def _fmt(v) -> str:
    if v is None:
        return "–"
    if isinstance(v, float):
        return f"{v:.3g}"
    if isinstance(v, list):
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    return str(v)


def _separation_plot(table: list[dict], modes: tuple[str, ...], path: Path) -> None:
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for ax, key in zip(axes, ("min_horizontal_m", "min_vertical_m"), strict=True):
        data = {m: [r[key] for r in table if r["mode"] == m and r[key] is not None] for m in (modes[-1], *modes[:-1])}
        top = max((max(v) for v in data.values() if v), default=1.0)
        bins = np.linspace(0.0, top, 30)
        for m, v in data.items():
            ax.hist(v, bins=bins, alpha=0.6, label=m)
        ax.set_xlabel(key.replace("_", " ").replace(" m", " [m]"))
        ax.set_ylabel("runs")
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _approach_plot(summary: dict, path: Path) -> None:
    """NMAC encounters per approach sector: unmitigated, then each variant (annotated: its risk
    ratio, the first variant's alone when there is one)."""
    approach = {key: s["bins"].get("approach", {}) for key, s in summary.items()}
    first = next(iter(approach.values()))
    labels = list(first)
    fig, ax = plt.subplots(figsize=(8, 4))
    x = np.arange(len(labels))
    bars = [("unmitigated", first, "nmac_unmitigated")] + [
        (f"{k} mitigated", a, "nmac_mitigated") for k, a in approach.items()
    ]
    width = 0.8 / len(bars)
    for j, (name, a, key) in enumerate(bars):
        off = (j - (len(bars) - 1) / 2) * width
        ax.bar(x + off, [a.get(k, {}).get(key, 0) for k in labels], width=width, label=name)
    for i, k in enumerate(labels):
        rr = " / ".join(_fmt(a.get(k, {}).get("risk_ratio")) for a in approach.values())
        ax.annotate(f"RR {rr}", (i, 0), textcoords="offset points", xytext=(0, -28), ha="center", fontsize=7)
    ax.set_xticks(x, labels, rotation=30, fontsize=7)
    ax.set_ylabel("NMAC encounters")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _scatter_plot(table: list[dict], mode: str, path: Path) -> None:
    mit = [r for r in table if r["mode"] == mode]
    unm = {r["encounter"]: r for r in table if r["mode"] == "unmitigated"}
    colours = {"NMAC": "red", "induced NMAC": "magenta", "LoWC": "orange", "incomplete": "grey", "clear": "green"}

    def label(r: dict) -> str:
        if r["nmac"]:
            return "induced NMAC" if not unm[r["encounter"]]["nmac"] else "NMAC"
        if not r["complete"]:
            return "incomplete"
        return "LoWC" if r["lowc"] else "clear"

    fig, ax = plt.subplots(figsize=(7, 5))
    for name, col in colours.items():
        pts = [r for r in mit if label(r) == name]
        if pts:
            ax.scatter([r["approach_angle"] % 360 for r in pts], [r["hmd"] for r in pts], c=col, s=14, label=name)
    ax.set_xlabel("approach angle [deg]")
    ax.set_ylabel("sampled HMD [m]")
    ax.set_title(f"{mode} outcome by sampled geometry")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_report(out: Path, c: Campaign, table: list[dict], summary: dict) -> Path:
    """Plots next to ``report.md`` in ``out``; returns the report's path."""
    failed = sum(r["status"] == "failed" for r in table)
    how = f"flown as {', '.join(f'`{m}`' for m in c.modes)}" if c.named else "flown mitigated and unmitigated"
    lines = [
        f"# Encounter campaign `{c.name}`",
        "",
        f"Ownship {c.setup.ownship['aircraft']} with planner `{c.planner}`; intruder: {c.setup.intruder['kind']}; "
        f"{len(c.encounters)} encounters, each {how} with the same seed. "
        f"NMAC cylinder {c.setup.metrics['nmac_horizontal']:.3g} m / ±{c.setup.metrics['nmac_vertical']:.3g} m; "
        f"failed runs: {failed}.",
        "",
        "| mitigated | " + " | ".join(SUMMARY_KEYS) + " |",
        "|---|" + "---|" * len(SUMMARY_KEYS),
        *("| " + key + " | " + " | ".join(_fmt(s.get(k)) for k in SUMMARY_KEYS) + " |" for key, s in summary.items()),
        "",
    ]
    if any(s.get("n") for s in summary.values()):
        _separation_plot(table, c.modes, out / "separation.png")
        _approach_plot(summary, out / "approach.png")
        lines += ["![minimum separation](separation.png)", "", "![NMAC by approach angle](approach.png)", ""]
        for v in c.variants:
            png = f"geometry_{v.name}.png" if c.named else "geometry.png"
            _scatter_plot(table, v.name, out / png)
            lines += [f"![{v.name}: geometry and outcome]({png})", ""]
        for key, s in summary.items():
            for name, groups in s.get("bins", {}).items():
                title = f"{key}: by {name.replace('_', ' ')}" if c.named else f"By {name.replace('_', ' ')}"
                lines += [f"## {title}", "", "| bin | " + " | ".join(SUMMARY_KEYS) + " |"]
                lines += ["|---|" + "---|" * len(SUMMARY_KEYS)]
                lines += [
                    "| " + lab + " | " + " | ".join(_fmt(g.get(k)) for k in SUMMARY_KEYS) + " |"
                    for lab, g in groups.items()
                ]
                lines.append("")
    kept = [r for r in table if r.get("mcap")]
    if kept:
        lines += ["## Kept logs", "", "| encounter | mode | status | NMAC | complete | min horizontal [m] | MCAP |"]
        lines += ["|---|---|---|---|---|---|---|"]
        lines += [
            f"| {r['encounter']} | {r['mode']} | {r['status']} | {r['nmac']} | {r['complete']} | "
            f"{_fmt(r['min_horizontal_m'])} | `{r['mcap']}` |"
            for r in kept
        ]
    path = out / "report.md"
    path.write_text("\n".join(lines) + "\n")
    return path
