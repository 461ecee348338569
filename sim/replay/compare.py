"""A/B comparison of two runs: every metric side by side with its difference."""

from __future__ import annotations

from pathlib import Path

from sim.replay.metrics import flatten
from sim.replay.report import log_metrics
from sim.replay.runlog import RunLog


def compare_logs(a: str | Path, b: str | Path) -> list[tuple[str, object, object, float | None]]:
    """Rows (metric, value in A, value in B, B - A where both are numbers)."""
    fa = flatten(log_metrics(RunLog(a)))
    fb = flatten(log_metrics(RunLog(b)))
    rows: list[tuple[str, object, object, float | None]] = []
    for k in sorted(set(fa) | set(fb)):
        x, y = fa.get(k), fb.get(k)
        numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (x, y))
        rows.append((k, x, y, (y - x) if numeric and x is not None and y is not None else None))
    return rows
