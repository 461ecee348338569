"""Reading run logs back: decoded messages per topic, the run's metadata, a summary for ``info``.

Sim time of a message = log time - the run's epoch (metadata ``run.epoch_ns``). Whatever is
wrong with a file (missing, not an MCAP, truncated, corrupt chunks, undecodable messages, a
foreign or hand-edited log) surfaces as one :class:`LogReadError` naming the file.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

from mcap.exceptions import McapError
from mcap.reader import SeekingReader
from mcap.records import Attachment, Channel, McapRecord, Message, Metadata, Schema
from mcap.stream_reader import MAGIC_SIZE, StreamReader
from mcap.summary import Summary
from mcap_protobuf.decoder import DecoderFactory

from sim.log_proto import PACKAGE, to_dict
from sim.mcap_order import messages_in_log_time_order

COSIM_PREFIX = f"{PACKAGE}."


class LogReadError(ValueError):
    """The file is missing, not an MCAP, or damaged beyond reading."""


@contextmanager
def _reading(path: Path, what: str) -> Iterator[None]:
    """Any failure of the MCAP, compression, protobuf or JSON libraries on the file's bytes as a
    LogReadError (they raise McapError, ZstdError, DecodeError, UnicodeDecodeError, KeyError,
    OverflowError, MemoryError... on hostile input)."""
    try:
        yield
    except LogReadError:
        raise
    except Exception as exc:  # noqa: BLE001 - see the docstring: the file's bytes are not trusted
        raise LogReadError(f"{path}: {what} ({type(exc).__name__}: {str(exc)[:200]})") from None


@contextmanager
def log_content(path: str | Path) -> Iterator[None]:
    """Decoded messages that are not what cosim logs (a foreign or hand-edited MCAP: missing
    fields, wrong types or shapes) as a LogReadError, around code that interprets them."""
    try:
        yield
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as exc:
        if isinstance(exc, LogReadError):
            raise
        raise LogReadError(f"{path}: not a cosim run log, or edited ({type(exc).__name__}: {str(exc)[:200]})") from None


@dataclass(frozen=True, slots=True)
class TopicInfo:
    topic: str
    schema: str
    encoding: str
    count: int
    metadata: dict[str, str]


@dataclass(frozen=True, slots=True)
class LogInfo:
    """``finished``: the file has its summary; ``False`` for a log whose writer never closed it
    (power loss, a killed writer, a full disk), read up to its last complete chunk."""

    path: Path
    profile: str
    library: str
    start_s: float
    end_s: float
    messages: int
    topics: list[TopicInfo]
    metadata: dict[str, dict[str, str]]
    attachments: list[str]
    finished: bool = True


_RECORD_LIMIT = 256 * 2**20  # no cosim record is near this; a corrupt length must not allocate GiBs


def _open(path: Path) -> BinaryIO:
    if not path.is_file():
        raise LogReadError(f"{path}: no such file")
    return open(path, "rb")


def _summary(reader: SeekingReader) -> Summary | None:
    """The file's summary, or None when the file was never finished (no footer or summary)."""
    try:
        return reader.get_summary()
    except (McapError, struct.error, EOFError, ValueError):
        return None


def _recovered_records(f) -> Iterator[McapRecord]:
    """The records of an unfinished file in order, up to the last complete chunk: the stream
    ends at the first record cut short or failing its CRC (the tail the writer never finished)."""
    f.seek(0)
    records = StreamReader(f, validate_crcs=True, record_size_limit=_RECORD_LIMIT).records
    while True:
        try:
            yield next(records)
        except StopIteration:
            return
        except (McapError, struct.error, EOFError, ValueError, OSError, MemoryError) as exc:
            if f.tell() <= MAGIC_SIZE:  # not even an MCAP header
                raise LogReadError(f"not an MCAP file ({type(exc).__name__})") from None
            return


def read_info(path: str | Path) -> LogInfo:
    """Summary of a log (topics, counts, time span, metadata); an unfinished log is read up to
    its last complete chunk (``finished`` False)."""
    path = Path(path)
    f = _open(path)
    with f, _reading(path, "not a readable MCAP file"):
        reader = SeekingReader(f, record_size_limit=_RECORD_LIMIT)
        header = reader.get_header()
        summary = _summary(reader)
        if summary is None:
            return _recovered_info(path, f, header)
        meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        attachments = [a.name for a in reader.iter_attachments()]
    epoch = _epoch(path, meta)
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


def _recovered_info(path: Path, f, header) -> LogInfo:
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    meta: dict[str, dict[str, str]] = {}
    attachments: list[str] = []
    for rec in _recovered_records(f):
        if isinstance(rec, Channel):
            channels[rec.id] = rec
        elif isinstance(rec, Schema):
            schemas[rec.id] = rec
        elif isinstance(rec, Metadata):
            meta[rec.name] = dict(rec.metadata)
        elif isinstance(rec, Attachment):
            attachments.append(rec.name)
    counts: dict[int, int] = {}
    times = []
    for _, ch, msg in _recovered_messages(f, None):
        counts[ch.id] = counts.get(ch.id, 0) + 1
        times.append(msg.log_time)
    epoch = _epoch(path, meta)
    topics = sorted(
        (
            TopicInfo(
                ch.topic,
                schemas[ch.schema_id].name if ch.schema_id in schemas else "",
                ch.message_encoding,
                counts.get(cid, 0),
                dict(ch.metadata),
            )
            for cid, ch in channels.items()
        ),
        key=lambda ti: ti.topic,
    )
    return LogInfo(
        path=path,
        profile=header.profile,
        library=header.library,
        start_s=(min(times) - epoch) / 1e9 if times else 0.0,
        end_s=(max(times) - epoch) / 1e9 if times else 0.0,
        messages=len(times),
        topics=topics,
        metadata=meta,
        attachments=attachments,
        finished=False,
    )


def read_attachment(path: str | Path, name: str) -> bytes | None:
    """The data of the attachment called ``name`` (e.g. ``scenario.toml``), or None."""
    path = Path(path)
    f = _open(path)
    with f, _reading(path, "damaged MCAP"):
        reader = SeekingReader(f, record_size_limit=_RECORD_LIMIT)
        found = reader.iter_attachments() if _summary(reader) is not None else _recovered_records(f)
        for a in found:
            if isinstance(a, Attachment) and a.name == name:
                return a.data
    return None


def read_attached_scenario(path: str | Path):
    """The validated scenario attached to a run log (``scenario.toml``), or None if there is
    none; ScenarioError if it no longer validates. Nowcast files are taken from where the run
    read them (metadata ``weather.nowcast_files``, absolute paths)."""
    from sim.input_files import parse_toml
    from sim.scenario import ScenarioError, parse_scenario

    raw = read_attachment(path, "scenario.toml")
    if raw is None:
        return None
    source = f"{path}:scenario.toml"
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise ScenarioError(f"{source}: not UTF-8") from None
    data = parse_toml(text, source, ScenarioError)
    files = read_info(path).metadata.get("weather", {}).get("nowcast_files")
    if files is not None and isinstance(data.get("weather"), dict):
        try:
            data["weather"]["nowcast_files"] = json.loads(files)
        except ValueError:
            raise LogReadError(f"{path}: metadata weather.nowcast_files is not JSON") from None
    return parse_scenario(data, source)


def iter_messages(path: str | Path, topics: list[str] | None = None) -> Iterator[tuple[str, float, Any]]:
    """(topic, sim time [s], decoded message) in log-time order; JSON and cosim's protobuf
    messages decode to dicts (the same dict either way, :func:`sim.log_proto.to_dict`), other
    protobuf (Foxglove types) to message objects."""
    path = Path(path)
    f = _open(path)
    with f, _reading(path, "damaged MCAP"):
        reader = SeekingReader(f, record_size_limit=_RECORD_LIMIT)
        summary = _summary(reader)
        if summary is not None:
            meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
            found = messages_in_log_time_order(reader, f, summary, topics)
        else:
            meta = {r.name: dict(r.metadata) for r in _recovered_records(f) if isinstance(r, Metadata)}
            found = _recovered_messages(f, topics)
        epoch = _epoch(path, meta)
        factory = DecoderFactory()  # per file: it caches decoders by schema id
        decoders: dict[int, Any] = {}
        for schema, channel, message in found:
            if channel.message_encoding == "json":
                decoded = json.loads(message.data)
            else:
                if schema is None:
                    raise LogReadError(f"{path}: {channel.topic}: {channel.message_encoding} message without a schema")
                dec = decoders.get(schema.id)
                if dec is None:
                    dec = factory.decoder_for(channel.message_encoding, schema)
                    if dec is None:
                        raise LogReadError(f"{path}: {channel.topic}: no decoder for {channel.message_encoding!r}")
                    decoders[schema.id] = dec
                decoded = dec(message.data)
                if schema.name.startswith(COSIM_PREFIX):
                    decoded = to_dict(decoded)
            yield channel.topic, (message.log_time - epoch) / 1e9, decoded


def _recovered_messages(f, topics: list[str] | None) -> Iterator[tuple[Schema | None, Channel, Message]]:
    """(schema, channel, message) of an unfinished file in file order (the writer's time order),
    without the messages of the last log time: the tick the file was cut in may be partial."""
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    tick: list[tuple[Schema | None, Channel, Message]] = []  # messages of the latest log time
    for rec in _recovered_records(f):
        if isinstance(rec, Message):
            ch = channels.get(rec.channel_id)
            if ch is None:
                raise LogReadError(f"message on unknown channel {rec.channel_id}")
            if tick and rec.log_time > tick[-1][2].log_time:
                yield from tick
                tick = []
            item = (schemas.get(ch.schema_id), ch, rec)
            if topics is not None and ch.topic not in topics:
                continue
            if tick and rec.log_time < tick[-1][2].log_time:
                yield item  # an earlier time than the tick in progress: complete
            else:
                tick.append(item)
        elif isinstance(rec, Channel):
            channels[rec.id] = rec
        elif isinstance(rec, Schema):
            schemas[rec.id] = rec


def _epoch(path: Path, meta: dict[str, dict[str, str]]) -> int:
    """Log time of sim time 0 [ns]: metadata ``run.epoch_ns`` (0 without it)."""
    try:
        return int(meta.get("run", {}).get("epoch_ns", 0))
    except ValueError:
        raise LogReadError(f"{path}: metadata run.epoch_ns is not an integer") from None


def read_topic(path: str | Path, topic: str) -> list[tuple[float, Any]]:
    """All messages of one topic as (sim time [s], decoded)."""
    return [(t, m) for _, t, m in iter_messages(path, [topic])]
