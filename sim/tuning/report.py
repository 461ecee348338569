"""Trim tables (CSV, Markdown) and plots (PNG) for people; failures listed with their reasons."""

from __future__ import annotations

import csv
import math
from pathlib import Path

from sim.tuning.trim_haps import TrimPoint

COLUMNS = (
    "method",
    "alt_m",
    "tas_mps",
    "eas_mps",
    "ok",
    "alpha_deg",
    "pitch_deg",
    "roll_deg",
    "elevator_norm",
    "throttle",
    "prop_rpm",
    "shaft_power_w",
    "stall_margin",
    "residual_acc",
    "residual_rot",
    "residual_model",
    "reason",
)


def _fmt(v) -> str:
    if isinstance(v, bool):
        return "yes" if v else "NO"
    if isinstance(v, float):
        if math.isnan(v):
            return ""
        if v != 0.0 and abs(v) < 1e-3:
            return f"{v:.1e}"
        if abs(v) >= 1000:
            return f"{v:.0f}"
        return f"{v:.4g}"
    return str(v)


def write_csv(rows: list[TrimPoint], path: Path) -> None:
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["airframe", *COLUMNS])
        w.writeheader()
        for r in rows:
            d = r.row()
            w.writerow({k: d[k] for k in ["airframe", *COLUMNS]})


def markdown(rows: list[TrimPoint], title: str) -> str:
    """A Markdown table of the trimmed points, then the list of failures with reasons."""
    cols = [c for c in COLUMNS if c != "reason"]
    lines = [
        f"# {title}",
        "",
        (
            "Units: m, m/s, deg, normalised surface/throttle, rpm, W; stall margin = EAS / 1-g stall EAS; residuals "
            "m/s^2 (translational), rad/s^2 (rotational), casadi model residual dimensionless."
        ),
        "",
        "| " + " | ".join(cols) + " |",
        "|" + "---|" * len(cols),
    ]
    lines += ["| " + " | ".join(_fmt(r.row()[c]) for c in cols) + " |" for r in rows if r.ok]
    bad = [r for r in rows if not r.ok]
    lines += ["", f"## Failures ({len(bad)} of {len(rows)})", ""]
    lines += [f"- {r.method} at {r.alt_m:.0f} m, {r.tas_mps:.1f} m/s: {r.reason}" for r in bad] or ["- none"]
    return "\n".join(lines) + "\n"


def plot(rows: list[TrimPoint], path: Path, title: str) -> None:
    """Throttle, alpha and pitch against TAS, one line per altitude and method."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.5))
    alts = sorted({r.alt_m for r in rows})
    methods = sorted({r.method for r in rows})
    styles = dict(zip(methods, ("-o", "--x", ":s"), strict=False))
    cmap = plt.get_cmap("viridis")
    for i, h in enumerate(alts):
        color = cmap(i / max(len(alts) - 1, 1))
        for m in methods:
            pts = sorted((r for r in rows if r.alt_m == h and r.method == m and r.ok), key=lambda r: r.tas_mps)
            if not pts:
                continue
            v = [p.tas_mps for p in pts]
            for ax, key in zip(axes, ("throttle", "alpha_deg", "pitch_deg"), strict=False):
                ax.plot(v, [getattr(p, key) for p in pts], styles[m], color=color, ms=4, label=f"{h / 1000:.1f} km {m}")
    for ax, lab in zip(axes, ("throttle [-]", "alpha [deg]", "pitch [deg]"), strict=False):
        ax.set_xlabel("true airspeed [m/s]")
        ax.set_ylabel(lab)
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=7, ncol=2)
    n_bad = sum(not r.ok for r in rows)
    fig.suptitle(f"{title} ({n_bad} failed points not drawn; see the table)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_all(rows: list[TrimPoint], out_dir: Path, stem: str, title: str) -> dict[str, Path]:
    """CSV, Markdown and PNG into ``out_dir``; returns their paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {"csv": out_dir / f"{stem}.csv", "md": out_dir / f"{stem}.md", "png": out_dir / f"{stem}.png"}
    write_csv(rows, paths["csv"])
    paths["md"].write_text(markdown(rows, title))
    plot(rows, paths["png"], title)
    return paths
