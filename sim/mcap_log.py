"""MCAP run log: Foxglove protobuf types where one fits, this project's protobuf messages
(:mod:`sim.log_proto`) for the high-rate topics, this project's JSON schemas elsewhere.

Log time of a message = scenario epoch + sim time [ns]; publish time = log time, so that two runs
of the same scenario and seed write byte-identical messages. Channels whose content is wall-clock
time (planner latency, planner runtimes) carry the channel metadata ``wallclock=true`` and
``wallclock_fields`` (the dotted paths of those fields) and are the only exception.

Writing: the simulation process only serialises messages (JSON with orjson, Foxglove protobuf;
this project's protobuf messages as pickled dicts, encoded by the writer; a vehicle's per-tick
topics as one row of floats per tick, :class:`RowBuffer`, whose messages the writer makes) and hands them in
batches to a writer process that owns the file and the ``mcap`` writer (record framing, indexes,
zstd chunks, the compact messages' encoding: taken off the simulation's core). The file
is finished in ``close()``, which the runner calls in a ``finally``; if the simulation process dies
without it (a crash of the flight model, SIGKILL), the writer process sees the pipe close and
finishes the file with every message it received, so the log stays readable. The writer is a
fresh interpreter (``python -m sim.mcap_writer``, which imports only ``mcap``) fed pickled
batches on its stdin, so it also starts inside daemonic workers (a Dask nanny's) and never re-runs
the caller's script; ``background=False`` writes the same records in-process. The writer runs in
its own session, so a signal to the whole process group (a terminal hang-up, ``kill -- -PGID``,
SIGKILL included) kills the simulation but not the writer, which then finishes the file. A log
whose writer died anyway (killed on its own, full disk) keeps every complete chunk:
:mod:`sim.mcap_read` reads it up to there.
"""

from __future__ import annotations

import contextlib
import json
import os
import pickle
import subprocess
import sys
from array import array
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

import orjson
from foxglove_schemas_protobuf.Log_pb2 import Log
from mcap_protobuf.schema import build_file_descriptor_set

from sim import log_proto, log_rows
from sim.mcap_writer import RecordWriter

ROWS = 32  # log ticks of a row buffer handed to the writer at once
LEVELS = {"debug": Log.DEBUG, "info": Log.INFO, "warning": Log.WARNING, "error": Log.ERROR, "fatal": Log.FATAL}
_BATCH = 128  # records per hand-over to the writer process (a few log ticks)


def sim_ns(t: float) -> int:
    """Sim time ``t`` [s] in the log's whole nanoseconds (a message's log time is the epoch plus this)."""
    return round(t * 1e9)


def logged_time(t: float) -> float:
    """Sim time [s] of a message logged at ``t`` [s] as it reads back from the log."""
    return sim_ns(t) / 1e9


class LogWriteError(RuntimeError):
    """The log could not be written (e.g. disk full); says why."""


PIPE_BYTES = 1 << 20  # the simulation runs this far ahead of a busy writer before a hand-over waits


def _widen_pipe(pipe: IO[bytes]) -> None:
    """Grow the pipe's kernel buffer to PIPE_BYTES (Linux; elsewhere, or above the system's
    limit, it keeps its size)."""
    with contextlib.suppress(ImportError, AttributeError, OSError):
        import fcntl

        fcntl.fcntl(pipe.fileno(), fcntl.F_SETPIPE_SZ, PIPE_BYTES)


class _WriterProcess:
    """The writer process (``python -m sim.mcap_writer``, a fresh interpreter: nothing of the
    caller's ``__main__`` is re-run): pickled record batches in on its stdin, ``None`` last; its
    stdout says why it failed."""

    def __init__(self, path: Path, chunk_size: int):
        root = str(Path(__file__).resolve().parents[1])
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")])))
        self._proc = subprocess.Popen(
            [sys.executable, "-m", "sim.mcap_writer", str(path), str(chunk_size)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            env=env,
            start_new_session=True,  # a signal to our process group (hang-up, kill) spares it
        )
        if self._proc.stdin is None or self._proc.stdout is None:
            raise LogWriteError(f"{path}: the writer process has no pipes")
        self._stdin: IO[bytes] = self._proc.stdin
        _widen_pipe(self._stdin)
        self._stdout: IO[bytes] = self._proc.stdout

    def send(self, batch: list[tuple], last: bool = False) -> None:
        """Hand ``batch`` over (flushed); ``last``: then tell the writer to finish the file."""
        pickle.dump(batch, self._stdin, protocol=pickle.HIGHEST_PROTOCOL)
        if last:
            pickle.dump(None, self._stdin)
        self._stdin.flush()

    def error(self) -> str:
        """Why the writer process stopped (its stdout line), after waiting for it."""
        with contextlib.suppress(OSError):
            self._stdin.close()
        out = self._stdout.read().decode(errors="replace").strip()
        code = self._proc.wait()
        return out or (f"the writer process stopped (exit code {code})" if code else "")


RowPart = tuple[str, tuple[str, ...], tuple, tuple[dict[str, str], ...]]  # layout, topics, static, metadata


class RowBuffer:
    """One vehicle's rows, one per log tick, in tick order, each made of parts (a row of a
    :mod:`sim.log_rows` layout written on its channels; which parts, its ``spec`` from
    :meth:`McapLog.row_spec`), handed to the writer ``ROWS`` rows at a time (and at the log's
    close) as one record."""

    def __init__(self, log: McapLog):
        self._log = log
        self._rows: list[tuple[tuple, list[Piece]]] = []
        log._row_buffers.append(self)

    def add(self, spec: tuple, pieces: list[Piece]) -> None:
        """One row as its pieces, one after the other: a list of columns, or ``(fn, arg)`` whose
        ``fn(arg)`` gives them when the block is handed over (for an ``arg`` nobody changes: the
        rows of a block are made in one go, which costs less than one at a time between
        simulation steps, whose work leaves the logging code and data out of the caches).
        The list is the caller's no more."""
        rows = self._rows
        rows.append((spec, pieces))
        if len(rows) >= ROWS:
            self.flush()

    def flush(self) -> None:
        """Hand the buffered rows to the writer now, with the records pending before them, as
        ``("rows", epoch_ns, specs, values)``: one spec per row (a spec repeated in a block is
        pickled once) and the rows' values, one row after the other, as the bytes of a float64
        array (integers and booleans as floats; one copy instead of pickling each float)."""
        if self._rows:
            values = array("d")
            put = values.fromlist
            for _, pieces in self._rows:
                for p in pieces:
                    if isinstance(p, list):
                        put(p)
                    else:
                        fn, arg = p
                        put(fn(arg))
            specs = [spec for spec, _ in self._rows]
            self._rows = []
            self._log._record(("rows", self._log.epoch_ns, specs, values.tobytes()))
            self._log._flush()


Piece = list[float] | tuple[Callable[[Any], list[float]], Any]


class McapLog:
    """Writes one run to ``path``. Topics are registered on first write."""

    def __init__(
        self,
        path: str | Path,
        epoch_ns: int,
        chunk_size: int = 512 * 1024,
        background: bool = True,
        compact: bool = True,
    ):
        """``background``: write in a child process (else in this one, e.g. to debug the writer);
        ``compact``: :meth:`write_record` writes protobuf where it can (else JSON throughout)."""
        self.path = Path(path)
        self.compact = compact
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.epoch_ns = int(epoch_ns)
        try:  # open errors surface here, in the caller, not later from the writer process
            open(self.path, "wb").close()
        except OSError as exc:
            raise LogWriteError(f"cannot write the log {self.path}: {exc.strerror or exc}") from None
        self._pending: list[tuple] = []
        self._proc: _WriterProcess | None = None
        self._inline: RecordWriter | None = None
        if background:
            self._proc = _WriterProcess(self.path, chunk_size)
        else:
            self._inline = RecordWriter(open(self.path, "wb"), chunk_size)  # noqa: SIM115 (the writer closes it)
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._seq: dict[int, int] = {}
        self._failure: str | None = None  # why the writer stopped: every later write says so
        self._row_buffers: list[RowBuffer] = []
        self.closed = False

    # -- registration --------------------------------------------------------------------
    def _schema(self, name: str, encoding: str, data_fn) -> int:
        sid = self._schemas.get(name)
        if sid is None:
            sid = self._schemas[name] = len(self._schemas) + 1
            self._record(("schema", sid, name, encoding, data_fn()))
        return sid

    def _channel(self, topic: str, encoding: str, schema_id: int, metadata: dict[str, str]) -> int:
        cid = self._channels[topic] = len(self._channels) + 1
        self._seq[cid] = 0
        self._record(("channel", cid, topic, encoding, schema_id, metadata or {}))
        return cid

    def _record(self, rec: tuple) -> None:
        if self._failure is not None:
            raise LogWriteError(self._failure)
        if self.closed:
            raise LogWriteError(f"{self.path}: the log is closed")
        self._pending.append(rec)
        if len(self._pending) >= _BATCH:
            self._flush()

    def _flush(self) -> None:
        batch, self._pending = self._pending, []
        if self._inline is not None:
            self._apply_inline(batch)
        elif self._proc is not None:
            try:
                self._proc.send(batch)  # handed over now: a crash after this loses none of it
            except OSError:
                self._failure = f"{self.path}: {self._proc.error()}"
                raise LogWriteError(self._failure) from None

    def _apply_inline(self, batch: list[tuple]) -> None:
        """Write ``batch`` here; a message that does not encode is a LogWriteError, as from the
        writer process."""
        assert self._inline is not None
        try:
            self._inline.apply(batch)
        except ValueError as exc:
            self._failure = f"{self.path}: ValueError: {exc}"
            raise LogWriteError(self._failure) from None

    # -- writing -------------------------------------------------------------------------
    def _add(self, cid: int, t: float, data: bytes) -> None:
        seq = self._seq[cid] = self._seq[cid] + 1
        self._record(("message", cid, self.epoch_ns + sim_ns(t), data, seq))

    def write_json(
        self, topic: str, t: float, obj: dict[str, Any], schema: dict, metadata: dict[str, str] | None = None
    ) -> None:
        """``obj`` (floats, lists, dicts, numpy arrays) as JSON on ``topic`` with a JSON Schema.
        Floats are written in their shortest exact form (they read back bit-identical); NaN and
        infinities become ``null``."""
        cid = self._channels.get(topic)
        if cid is None:
            sid = self._schema(schema["title"], "jsonschema", lambda: json.dumps(schema, sort_keys=True).encode())
            cid = self._channel(topic, "json", sid, metadata or {})
        self._add(cid, t, orjson.dumps(obj, option=orjson.OPT_SERIALIZE_NUMPY))

    def write_record(
        self, topic: str, t: float, obj: dict[str, Any], schema: dict, metadata: dict[str, str] | None = None
    ) -> None:
        """``obj`` as in :meth:`write_json`, in protobuf when the log is compact and
        :mod:`sim.log_proto` has the schema's message (NaN then stays NaN on the wire and reads
        back as None, as JSON's null does), else in JSON. The protobuf encoding is done by the
        writer (off the simulation's core: here ``obj`` is only pickled, at once); a key the
        message lacks stops the writer, and the next hand-over or ``close`` raises
        LogWriteError saying so."""
        title = schema["title"]
        if not (self.compact and log_proto.has_schema(title)):
            self.write_json(topic, t, obj, schema, metadata)
            return
        cid = self._channels.get(topic)
        if cid is None:
            sid = self._schema(title, "protobuf", lambda: log_proto.schema_data(title))
            cid = self._channel(topic, "protobuf", sid, metadata or {})
        seq = self._seq[cid] = self._seq[cid] + 1
        obj_now = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)  # later changes to obj are not logged
        self._record(("proto", cid, self.epoch_ns + sim_ns(t), title, obj_now, seq))

    def write_proto(self, topic: str, t: float, message, metadata: dict[str, str] | None = None) -> None:
        """A protobuf message (e.g. a Foxglove schema) on ``topic``."""
        cid = self._channels.get(topic)
        if cid is None:
            cls = type(message)
            sid = self._schema(
                cls.DESCRIPTOR.full_name, "protobuf", lambda: build_file_descriptor_set(cls).SerializeToString()
            )
            cid = self._channel(topic, "protobuf", sid, metadata or {})
        self._add(cid, t, message.SerializeToString(deterministic=True))

    def row_spec(self, parts: tuple[RowPart, ...]) -> tuple:
        """The spec of rows made of ``parts``: (layout, topics, static, metadata), the topics one
        per output of the layout (a new channel registered with its metadata entry),
        ``static`` the part's constant values (map keys, frame name, sensor counts). A JSON
        log writes :meth:`write_json` records instead (it has no rows)."""
        cids = []
        for layout, topics, _, metadata in parts:
            outputs = log_rows.LAYOUTS[layout].outputs
            if len(topics) != len(outputs):
                raise ValueError(f"row layout {layout!r} writes {len(outputs)} topics, got {len(topics)}")
            ids = []
            for topic, out, meta in zip(topics, outputs, metadata or ({},) * len(topics), strict=True):
                cid = self._channels.get(topic)
                if cid is None:
                    sid = self._schema(out.schema, "protobuf", out.schema_data)
                    cid = self._channel(topic, "protobuf", sid, meta)
                ids.append(cid)
            cids.append(tuple(ids))
        return (tuple((p[0], p[2]) for p in parts), tuple(cids))

    def event(self, t: float, text: str, level: str = "info", name: str = "cosim") -> None:
        """A ``foxglove.Log`` on ``/log`` (mission events, mode changes, errors)."""
        ns = self.epoch_ns + sim_ns(t)
        msg = Log(level=LEVELS[level], message=text, name=name)
        msg.timestamp.FromNanoseconds(ns)
        self.write_proto("/log", t, msg)

    def metadata(self, name: str, data: dict[str, object]) -> None:
        """A metadata record ``name``; values are written as their ``str``."""
        self._record(("metadata", name, {k: str(v) for k, v in data.items()}))

    def attach(self, name: str, data: bytes, media_type: str, t: float = 0.0) -> None:
        ns = self.epoch_ns + sim_ns(t)
        self._record(("attachment", ns, name, media_type, data))

    def close(self) -> None:
        """Finish the file (summary, indexes) and wait for the writer; safe to call twice.
        Raises LogWriteError if the writer failed."""
        if self.closed:
            return
        try:
            if self._failure is None:
                for buf in self._row_buffers:
                    buf.flush()
        finally:
            self.closed = True
        if self._failure is not None:
            raise LogWriteError(self._failure)
        if self._inline is not None:
            try:
                self._apply_inline(self._pending)
            finally:
                self._inline.finish()
            return
        if self._proc is None:
            return
        with contextlib.suppress(OSError):  # the writer is gone: its error line says why
            self._proc.send(self._pending, last=True)
        self._pending = []
        error = self._proc.error()
        if error:
            raise LogWriteError(f"{self.path}: {error}")

    def __enter__(self) -> McapLog:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
