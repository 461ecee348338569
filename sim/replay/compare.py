"""A/B comparison of two runs: every metric side by side with its difference."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import TextIO

from sim.replay.metrics import flatten
from sim.replay.report import log_metrics

Row = tuple[str, object, object, float | None]
COLUMNS = ("metric", "a", "b", "b_minus_a")


def compare_logs(a: str | Path, b: str | Path) -> list[Row]:
    """Rows (metric, value in A, value in B, B - A where both are numbers)."""
    fa = flatten(log_metrics(a))
    fb = flatten(log_metrics(b))
    rows: list[Row] = []
    for k in sorted(set(fa) | set(fb)):
        x, y = fa.get(k), fb.get(k)
        rows.append((k, x, y, _difference(x, y)))
    return rows


def _difference(x: object, y: object) -> float | None:
    """y - x for two numbers (not flags), else None."""
    if isinstance(x, bool) or isinstance(y, bool) or not isinstance(x, int | float) or not isinstance(y, int | float):
        return None
    return y - x


def write_json(rows: list[Row], out: TextIO) -> None:
    """Rows as a JSON list of {metric, a, b, b_minus_a} (values as computed; null where absent)."""
    json.dump([dict(zip(COLUMNS, r, strict=True)) for r in rows], out, indent=1)
    out.write("\n")


def write_csv(rows: list[Row], out: TextIO) -> None:
    """Rows as CSV with a header; numbers in their shortest exact form, lists and objects as
    JSON, an absent value empty."""
    w = csv.writer(out, lineterminator="\n")
    w.writerow(COLUMNS)
    w.writerows([_csv_cell(v) for v in r] for r in rows)


def _csv_cell(v: object) -> object:
    if v is None:
        return ""
    return json.dumps(v) if isinstance(v, (list, dict)) else v
