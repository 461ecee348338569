"""The MCAP writing half of :mod:`sim.mcap_log`: applies log records to an ``mcap`` writer, in
the simulation process or as the writer process (``python -m sim.mcap_writer PATH CHUNK_SIZE``,
fed pickled batches on stdin). Imports only ``mcap`` (and :mod:`sim.log_proto`, :mod:`sim.log_rows` at the
first compact message), so the writer process starts quickly."""

from __future__ import annotations

import contextlib
import pickle
import signal
import sys
from array import array
from collections.abc import Callable
from functools import cached_property

from mcap.writer import CompressionType, Writer

from sim import __version__

PROFILE = "cosim"


class RecordWriter:
    """Applies log records to an ``mcap`` writer. Records are tuples: ``("schema", id, name,
    encoding, data)``, ``("channel", id, topic, encoding, schema_id, metadata)``, ``("message",
    channel_id, time_ns, data, sequence)``, ``("proto", channel_id, time_ns, title, pickled dict,
    sequence)`` (a message to encode with :func:`sim.log_proto.encode`, imported at the first),
    ``("rows", epoch_ns, specs, values)`` (a block of rows made of :mod:`sim.log_rows` parts,
    imported at the first; values: float64 bytes),
    ``("metadata", name, data)``, ``("attachment", time_ns, name, media_type, data)``. Ids are the
    log's own; mcap's are looked up."""

    def __init__(self, file, chunk_size: int):
        self.file = file
        self.writer = Writer(file, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        self.writer.start(profile=PROFILE, library=f"cosim {__version__}")
        self.schemas: dict[int, int] = {}
        self.channels: dict[int, int] = {}
        self.row_seq: dict[int, int] = {}  # per mcap channel: the last row message's sequence

    def apply(self, records: list[tuple]) -> None:
        w, channels = self.writer, self.channels
        for r in records:
            kind = r[0]
            if kind == "message":
                w.add_message(channels[r[1]], log_time=r[2], data=r[3], publish_time=r[2], sequence=r[4])
            elif kind == "proto":
                data = self._encode(r[3], pickle.loads(r[4]))
                w.add_message(channels[r[1]], log_time=r[2], data=data, publish_time=r[2], sequence=r[5])
            elif kind == "rows":
                self._rows(*r[1:])
            elif kind == "channel":
                channels[r[1]] = w.register_channel(r[2], r[3], self.schemas[r[4]], r[5])
            elif kind == "schema":
                self.schemas[r[1]] = w.register_schema(r[2], r[3], r[4])
            elif kind == "metadata":
                w.add_metadata(r[1], r[2])
            elif kind == "attachment":
                w.add_attachment(create_time=r[1], log_time=r[1], name=r[2], media_type=r[3], data=r[4])
            else:
                raise ValueError(f"unknown log record {kind!r}")

    def _rows(self, epoch_ns: int, specs: list[tuple], data: bytes) -> None:
        """A block of rows: ``specs`` one per row, each (parts ``(layout, static)`` of
        :mod:`sim.log_rows`, their channel ids), and the rows' values one after the other as the
        bytes of a float64 array; each part's messages, one per channel, logged at the epoch
        plus the part's sim time (its first column) and numbered per channel (row channels
        carry only rows)."""
        from sim.log_rows import row_width

        add, seq = self.writer.add_message, self.row_seq
        values = array("d", data).tolist()
        plans: dict[int, list] = {}  # per spec object of this block (unpickled once)
        for spec in specs:
            if id(spec) not in plans:
                parts, cids = spec
                plans[id(spec)] = [
                    (
                        row_width(layout, static),
                        static,
                        [(self.channels[c], o.build) for c, o in zip(ids, outs, strict=True)],
                    )
                    for (layout, static), ids in zip(parts, cids, strict=True)
                    for outs in [self._layouts[layout].outputs]
                ]
        width = sum(w for spec in specs for w, _, _ in plans[id(spec)])
        if width != len(values):
            raise ValueError(f"a block of rows has {len(values)} values, its specs take {width}")
        k = 0
        for spec in specs:
            for width, static, outputs in plans[id(spec)]:
                part = values[k : k + width]
                k += width
                t_ns = epoch_ns + round(part[0] * 1e9)
                for ch, build in outputs:
                    seq[ch] = n = seq.get(ch, 0) + 1
                    add(ch, log_time=t_ns, data=build(part, t_ns, static), publish_time=t_ns, sequence=n)

    @cached_property
    def _layouts(self):
        from sim.log_rows import LAYOUTS

        return LAYOUTS

    @cached_property
    def _encode(self) -> Callable[[str, dict], bytes]:
        from sim.log_proto import encode

        return encode

    def finish(self) -> None:
        try:
            self.writer.finish()
        finally:
            self.file.close()


def writer_main(path: str, chunk_size: int) -> int:
    """Writer process (``python -m sim.mcap_writer PATH CHUNK_SIZE``, started in its own session
    so that signals to the simulation's process group do not reach it): applies the pickled
    batches read from stdin until ``None`` (close) or end of file (the simulation process died:
    the pipe is its parent-death watch), finishes the file and prints an error line on stdout if
    anything failed. Every batch is flushed to the OS, so even a killed writer leaves the file
    readable up to its last complete chunk. A write that fails (full disk, file size limit) stops
    the writing there: the file keeps its complete chunks and the error line says why."""
    for sig in (signal.SIGINT, signal.SIGHUP, signal.SIGXFSZ):  # SIGXFSZ: a size limit is an OSError
        signal.signal(sig, signal.SIG_IGN)
    src = sys.stdin.buffer
    try:
        rw = RecordWriter(open(path, "wb"), chunk_size)  # noqa: SIM115 - RecordWriter closes it
    except OSError as exc:
        print(f"cannot open {path}: {exc.strerror or exc}", flush=True)
        return 1
    error = None
    try:
        while (batch := _next_batch(src)) is not None:
            rw.apply(batch)
            rw.file.flush()
        rw.finish()
    except OSError as exc:
        error = f"{exc.strerror or exc}: the log ends at its last complete chunk"
        with contextlib.suppress(OSError):
            rw.file.close()
    except Exception as exc:  # noqa: BLE001 - reported to the simulation process at its next hand-over or close
        error = f"{type(exc).__name__}: {exc}"
        with contextlib.suppress(Exception):
            rw.finish()
    if error:
        print(error, flush=True)
        return 1
    return 0


def _next_batch(src) -> list[tuple] | None:
    """The next batch, or None at the close marker or the end of the pipe."""
    try:
        return pickle.load(src)
    except EOFError:
        return None


if __name__ == "__main__":
    sys.exit(writer_main(sys.argv[1], int(sys.argv[2])))
