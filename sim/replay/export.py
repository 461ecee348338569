"""Export a run log's topics to Parquet or CSV: one file per topic, as :func:`sim.replay.frame.frame`
tables (dotted columns, index ``sim_time_s`` = sim time [s]), written by streaming.

The log is read twice, message by message: the first pass finds each topic's columns (in order
of first appearance) and the type each column holds over the whole topic, the second writes the
rows in batches of ``batch`` (a Parquet row group each, or CSV lines appended), so memory holds
one batch per topic whatever the log's length. Column types are those of the whole-topic table:
integers with gaps or mixed with floats are float64, booleans or text with gaps stay nullable.

A topic's file is its name without the leading slash and with ``/`` as ``.``:
``/haps/truth/state`` -> ``haps.truth.state.parquet``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

from sim.mcap_read import LogReadError, iter_messages, read_info
from sim.replay.frame import INDEX, Scalar, as_dict, flatten_message, frame

if TYPE_CHECKING:
    import pandas as pd
    import pyarrow as pa
    import pyarrow.parquet as pq

FORMATS = ("parquet", "csv")
BATCH = 1024  # rows per write (a Parquet row group)

ProgressFn = Callable[[int, int], None]  # (messages read, messages to read: each topic's twice)


def topic_file(topic: str, fmt: str) -> str:
    """The file name a topic exports to."""
    return f"{topic.strip('/').replace('/', '.')}.{fmt}"


class _Columns:
    """A topic's columns in order of first appearance, the Python types each holds, its rows."""

    def __init__(self) -> None:
        self.types: dict[str, set[type]] = {}
        self.filled: dict[str, int] = {}  # rows with a value (not None) in the column
        self.rows = 0

    def add(self, row: dict[str, Scalar]) -> None:
        self.rows += 1
        for name, value in row.items():
            self.types.setdefault(name, set())
            if value is not None:
                self.types[name].add(type(value))
                self.filled[name] = self.filled.get(name, 0) + 1

    def dtype(self, name: str) -> str:
        """The column's pandas dtype in the whole-topic table."""
        types, full = self.types[name], self.filled.get(name, 0) == self.rows
        if types == {bool} and full:
            return "bool"
        if types == {int} and full:
            return "int64"
        if types and types <= {int, float}:
            return "float64"
        return "object"

    def arrow_type(self, name: str) -> pa.DataType:
        import pyarrow as pa

        types = self.types[name]
        simple = {"bool": pa.bool_(), "int64": pa.int64(), "float64": pa.float64()}.get(self.dtype(name))
        if simple is not None:
            return simple
        if not types:
            return pa.null()
        if types == {bool}:
            return pa.bool_()
        if types == {str}:
            return pa.string()
        raise ValueError(f"column {name!r} mixes {', '.join(sorted(t.__name__ for t in types))}: no Parquet type")


class _TopicWriter:
    """One topic's file, written a batch of rows at a time."""

    def __init__(self, target: Path, fmt: str, columns: _Columns, batch: int):
        self.target, self.fmt, self.columns, self.batch = target, fmt, columns, batch
        self.times: list[float] = []
        self.rows: list[dict[str, Scalar]] = []
        self.parquet: pq.ParquetWriter | None = None
        self.schema: pa.Schema | None = None
        self.csv: TextIO | None = None

    def add(self, t: float, row: dict[str, Scalar]) -> None:
        self.times.append(t)
        self.rows.append(row)
        if len(self.rows) >= self.batch:
            self.flush()

    def flush(self) -> None:
        if not self.rows:
            return
        import pandas as pd

        names = list(self.columns.types)
        df = pd.DataFrame.from_records(
            self.rows, columns=names, index=pd.Index(self.times, dtype=float, name=INDEX)
        ).astype({n: self.columns.dtype(n) for n in names})
        self.times, self.rows = [], []
        if self.fmt == "parquet":
            self._parquet(df)
        else:
            if self.csv is None:
                self.csv = open(self.target, "w", newline="")  # noqa: SIM115 - closed in close()
                df.to_csv(self.csv)
            else:
                df.to_csv(self.csv, header=False)

    def _parquet(self, df: pd.DataFrame) -> None:
        import pyarrow as pa
        import pyarrow.parquet as pq

        if self.schema is None:
            fields = [pa.field(n, self.columns.arrow_type(n)) for n in self.columns.types]
            self.schema = pa.schema([*fields, pa.field(INDEX, pa.float64())])
        table = pa.Table.from_pandas(df, schema=self.schema, preserve_index=True)
        if self.parquet is None:
            self.parquet = pq.ParquetWriter(self.target, table.schema)
        self.parquet.write_table(table)

    def close(self) -> None:
        """Write the last rows and finish the file (a topic without messages: an empty table)."""
        self.flush()
        if self.parquet is not None:
            self.parquet.close()
        elif self.csv is not None:
            self.csv.close()
        elif self.fmt == "parquet":
            frame([], []).to_parquet(self.target)
        else:
            frame([], []).to_csv(self.target)


def export_log(
    log: str | Path,
    out_dir: str | Path,
    fmt: str,
    topics: list[str] | None = None,
    progress: ProgressFn | None = None,
    batch: int = BATCH,
) -> list[Path]:
    """Write each topic of ``log`` (default: all) to ``out_dir`` as ``fmt``; returns the files.
    Unknown topics and formats are a ValueError (LogReadError for topics) naming the known ones."""
    if fmt not in FORMATS:
        raise ValueError(f"unknown export format {fmt!r} (known: {', '.join(FORMATS)})")
    if batch < 1:
        raise ValueError(f"batch must be at least 1 row, got {batch}")
    path = Path(log)
    info = read_info(path)
    counts = {ti.topic: ti.count for ti in info.topics}
    selected = sorted(counts) if not topics else list(dict.fromkeys(topics))
    unknown = [t for t in selected if t not in counts]
    if unknown:
        raise LogReadError(f"{path}: no topic {', '.join(map(repr, unknown))} (has: {', '.join(sorted(counts))})")
    if fmt == "parquet":
        import pyarrow  # noqa: F401  (a clear ImportError before reading a long log)
    messages = sum(counts[t] for t in selected)
    total = 2 * messages
    columns = {t: _Columns() for t in selected}
    for k, (topic, _, row) in enumerate(_rows(path, selected), start=1):
        columns[topic].add(row)
        _report(progress, k, total)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    writers = {t: _TopicWriter(out / topic_file(t, fmt), fmt, columns[t], batch) for t in selected}
    for k, (topic, t, row) in enumerate(_rows(path, selected), start=messages + 1):
        writers[topic].add(t, row)
        _report(progress, k, total)
    for w in writers.values():
        w.close()
    return [w.target for w in writers.values()]


def _rows(path: Path, topics: list[str]) -> Iterator[tuple[str, float, dict[str, Scalar]]]:
    """(topic, sim time [s], flattened row) of every message of ``topics``, in log order."""
    for topic, t, msg in iter_messages(path, topics):
        yield topic, t, flatten_message(as_dict(msg))


def _report(progress: ProgressFn | None, k: int, total: int) -> None:
    if progress is not None and (k % 10_000 == 0 or k == total):
        progress(k, total)
