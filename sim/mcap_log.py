"""MCAP run log: Foxglove protobuf types where one fits, this project's JSON schemas elsewhere.

Log time of a message = scenario epoch + sim time [ns]; publish time = log time, so that two runs
of the same scenario and seed write byte-identical messages. Channels whose content is wall-clock
time (planner latency) carry the channel metadata ``wallclock=true`` and are the only exception.
The file is finished in ``close()``; the runner calls it in a ``finally``, so an exception or
Ctrl-C still leaves a readable log holding every message up to the last tick.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import orjson
from foxglove_schemas_protobuf.Log_pb2 import Log
from mcap.writer import CompressionType, Writer
from mcap_protobuf.schema import build_file_descriptor_set

from sim import __version__

PROFILE = "cosim"
LEVELS = {"debug": Log.DEBUG, "info": Log.INFO, "warning": Log.WARNING, "error": Log.ERROR,
          "fatal": Log.FATAL}


class McapLog:
    """Writes one run to ``path``. Topics are registered on first write."""

    def __init__(self, path: str | Path, epoch_ns: int, chunk_size: int = 512 * 1024):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.epoch_ns = int(epoch_ns)
        self._file = open(self.path, "wb")
        self._writer = Writer(self._file, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        self._writer.start(profile=PROFILE, library=f"cosim {__version__}")
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._seq: dict[int, int] = {}
        self.closed = False

    # -- registration --------------------------------------------------------------------
    def _schema(self, name: str, encoding: str, data_fn) -> int:
        sid = self._schemas.get(name)
        if sid is None:
            sid = self._schemas[name] = self._writer.register_schema(name, encoding, data_fn())
        return sid

    def _channel(self, topic: str, encoding: str, schema_id: int, metadata: dict[str, str]) -> int:
        cid = self._writer.register_channel(topic, encoding, schema_id, metadata or {})
        self._channels[topic] = cid
        self._seq[cid] = 0
        return cid

    # -- writing -------------------------------------------------------------------------
    def _add(self, cid: int, t: float, data: bytes) -> None:
        ns = self.epoch_ns + round(t * 1e9)
        seq = self._seq[cid] = self._seq[cid] + 1
        self._writer.add_message(cid, log_time=ns, data=data, publish_time=ns, sequence=seq)

    def write_json(self, topic: str, t: float, obj: dict[str, Any], schema: dict,
                   metadata: dict[str, str] | None = None) -> None:
        """``obj`` (floats, lists, dicts, numpy arrays) as JSON on ``topic`` with a JSON Schema.
        Floats are written in their shortest exact form (they read back bit-identical); NaN and
        infinities become ``null``."""
        cid = self._channels.get(topic)
        if cid is None:
            sid = self._schema(schema["title"], "jsonschema",
                               lambda: json.dumps(schema, sort_keys=True).encode())
            cid = self._channel(topic, "json", sid, metadata or {})
        self._add(cid, t, orjson.dumps(obj, option=orjson.OPT_SERIALIZE_NUMPY))

    def write_proto(self, topic: str, t: float, message, metadata: dict[str, str] | None = None) -> None:
        """A protobuf message (e.g. a Foxglove schema) on ``topic``."""
        cid = self._channels.get(topic)
        if cid is None:
            cls = type(message)
            sid = self._schema(cls.DESCRIPTOR.full_name, "protobuf",
                               lambda: build_file_descriptor_set(cls).SerializeToString())
            cid = self._channel(topic, "protobuf", sid, metadata or {})
        self._add(cid, t, message.SerializeToString(deterministic=True))

    def event(self, t: float, text: str, level: str = "info", name: str = "cosim") -> None:
        """A ``foxglove.Log`` on ``/log`` (mission events, mode changes, errors)."""
        ns = self.epoch_ns + round(t * 1e9)
        msg = Log(level=LEVELS[level], message=text, name=name)
        msg.timestamp.FromNanoseconds(ns)
        self.write_proto("/log", t, msg)

    def metadata(self, name: str, data: dict[str, str]) -> None:
        self._writer.add_metadata(name, {k: str(v) for k, v in data.items()})

    def attach(self, name: str, data: bytes, media_type: str, t: float = 0.0) -> None:
        ns = self.epoch_ns + round(t * 1e9)
        self._writer.add_attachment(create_time=ns, log_time=ns, name=name, media_type=media_type, data=data)

    def close(self) -> None:
        """Finish the file (summary, indexes); safe to call twice."""
        if self.closed:
            return
        self.closed = True
        try:
            self._writer.finish()
        finally:
            self._file.close()

    def __enter__(self) -> "McapLog":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
