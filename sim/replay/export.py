"""Export a run log's topics to Parquet or CSV: one file per topic, as :func:`sim.replay.frame.frame`
tables (dotted columns, index ``sim_time_s`` = sim time [s]).

A topic's file is its name without the leading slash and with ``/`` as ``.``:
``/haps/truth/state`` -> ``haps.truth.state.parquet``.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from sim.mcap_read import LogReadError, iter_messages, read_info
from sim.replay.frame import frame

FORMATS = ("parquet", "csv")

ProgressFn = Callable[[int, int], None]  # (messages read, messages in the selected topics)


def topic_file(topic: str, fmt: str) -> str:
    """The file name a topic exports to."""
    return f"{topic.strip('/').replace('/', '.')}.{fmt}"


def export_log(
    log: str | Path,
    out_dir: str | Path,
    fmt: str,
    topics: list[str] | None = None,
    progress: ProgressFn | None = None,
) -> list[Path]:
    """Write each topic of ``log`` (default: all) to ``out_dir`` as ``fmt``; returns the files.
    Unknown topics and formats are a ValueError (LogReadError for topics) naming the known ones."""
    if fmt not in FORMATS:
        raise ValueError(f"unknown export format {fmt!r} (known: {', '.join(FORMATS)})")
    path = Path(log)
    info = read_info(path)
    counts = {ti.topic: ti.count for ti in info.topics}
    selected = sorted(counts) if not topics else list(dict.fromkeys(topics))
    unknown = [t for t in selected if t not in counts]
    if unknown:
        raise LogReadError(f"{path}: no topic {', '.join(map(repr, unknown))} (has: {', '.join(sorted(counts))})")
    if fmt == "parquet":
        import pyarrow  # noqa: F401  (a clear ImportError before reading a long log)
    total = sum(counts[t] for t in selected)
    times: dict[str, list[float]] = {t: [] for t in selected}
    messages: dict[str, list[Any]] = {t: [] for t in selected}
    for k, (topic, t, msg) in enumerate(iter_messages(path, selected), start=1):
        times[topic].append(t)
        messages[topic].append(msg)
        if progress is not None and (k % 10_000 == 0 or k == total):
            progress(k, total)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = []
    for topic in selected:
        df = frame(times.pop(topic), messages.pop(topic))
        target = out / topic_file(topic, fmt)
        if fmt == "parquet":
            df.to_parquet(target)
        else:
            df.to_csv(target)
        files.append(target)
    return files
