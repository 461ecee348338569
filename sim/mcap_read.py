"""Reading run logs back: decoded messages per topic, the run's metadata, a summary for ``info``.

Sim time of a message = log time - the run's epoch (metadata ``run.epoch_ns``).
"""

from __future__ import annotations

import json
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory


class LogReadError(ValueError):
    """The file is missing, not an MCAP, or damaged beyond reading."""


# what the mcap reader raises on damaged input (truncation surfaces as struct/OS errors)
_READ_ERRORS = (McapError, struct.error, OSError, EOFError)


@dataclass(frozen=True, slots=True)
class TopicInfo:
    topic: str
    schema: str
    encoding: str
    count: int
    metadata: dict[str, str]


@dataclass(frozen=True, slots=True)
class LogInfo:
    path: Path
    profile: str
    library: str
    start_s: float
    end_s: float
    messages: int
    topics: list[TopicInfo]
    metadata: dict[str, dict[str, str]]
    attachments: list[str]


def _open(path: str | Path) -> tuple[Path, BinaryIO]:
    path = Path(path)
    if not path.is_file():
        raise LogReadError(f"{path}: no such file")
    return path, open(path, "rb")


def read_info(path: str | Path) -> LogInfo:
    """Summary of a finished log (topics, counts, time span, metadata)."""
    path, f = _open(path)
    with f:
        try:
            reader = make_reader(f)
            header = reader.get_header()
            summary = reader.get_summary()
            if summary is None:
                raise LogReadError(
                    f"{path}: the MCAP has no summary (the run was killed before it could finish the file)"
                )
            meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
            attachments = [a.name for a in reader.iter_attachments()]
        except _READ_ERRORS as exc:
            raise LogReadError(f"{path}: not a readable MCAP file ({exc or type(exc).__name__})") from None
    epoch = int(meta.get("run", {}).get("epoch_ns", 0))
    stats = summary.statistics
    counts = stats.channel_message_counts if stats else {}
    topics = sorted(
        (
            TopicInfo(
                ch.topic,
                summary.schemas[ch.schema_id].name if ch.schema_id else "",
                ch.message_encoding,
                counts.get(cid, 0),
                dict(ch.metadata),
            )
            for cid, ch in summary.channels.items()
        ),
        key=lambda ti: ti.topic,
    )
    return LogInfo(
        path=Path(path),
        profile=header.profile,
        library=header.library,
        start_s=((stats.message_start_time - epoch) / 1e9) if stats and stats.message_count else 0.0,
        end_s=((stats.message_end_time - epoch) / 1e9) if stats and stats.message_count else 0.0,
        messages=stats.message_count if stats else 0,
        topics=topics,
        metadata=meta,
        attachments=attachments,
    )


def read_attachment(path: str | Path, name: str) -> bytes | None:
    """The data of the attachment called ``name`` (e.g. ``scenario.toml``), or None."""
    path, f = _open(path)
    with f:
        try:
            for a in make_reader(f).iter_attachments():
                if a.name == name:
                    return a.data
        except _READ_ERRORS as exc:
            raise LogReadError(f"{path}: damaged MCAP ({exc or type(exc).__name__})") from None
    return None


def read_attached_scenario(path: str | Path):
    """The validated scenario attached to a run log (``scenario.toml``), or None if there is
    none; ScenarioError if it no longer validates. Nowcast files are taken from where the run
    read them (metadata ``weather.nowcast_files``, absolute paths)."""
    import tomllib

    from sim.scenario import parse_scenario

    raw = read_attachment(path, "scenario.toml")
    if raw is None:
        return None
    data = tomllib.loads(raw.decode())
    files = read_info(path).metadata.get("weather", {}).get("nowcast_files")
    if files is not None and isinstance(data.get("weather"), dict):
        data["weather"]["nowcast_files"] = json.loads(files)
    return parse_scenario(data, f"{path}:scenario.toml")


def iter_messages(path: str | Path, topics: list[str] | None = None) -> Iterator[tuple[str, float, Any]]:
    """(topic, sim time [s], decoded message) in log-time order; JSON decodes to dicts,
    protobuf to message objects."""
    path, f = _open(path)
    with f:
        try:
            reader = make_reader(f)
            meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
            epoch = int(meta.get("run", {}).get("epoch_ns", 0))
            factory = DecoderFactory()  # per file: it caches decoders by schema id
            decoders: dict[int, Any] = {}
            for schema, channel, message in reader.iter_messages(topics=topics, log_time_order=True):
                if channel.message_encoding == "json":
                    decoded = json.loads(message.data)
                else:
                    if schema is None:
                        raise LogReadError(f"{path}: channel {channel.topic} has no schema")
                    dec = decoders.get(schema.id)
                    if dec is None:
                        dec = factory.decoder_for(channel.message_encoding, schema)
                        if dec is None:
                            raise LogReadError(f"{path}: no decoder for {channel.message_encoding} on {channel.topic}")
                        decoders[schema.id] = dec
                    decoded = dec(message.data)
                yield channel.topic, (message.log_time - epoch) / 1e9, decoded
        except _READ_ERRORS as exc:
            raise LogReadError(f"{path}: damaged MCAP ({exc or type(exc).__name__})") from None


def read_topic(path: str | Path, topic: str) -> list[tuple[float, Any]]:
    """All messages of one topic as (sim time [s], decoded)."""
    return [(t, m) for _, t, m in iter_messages(path, [topic])]
