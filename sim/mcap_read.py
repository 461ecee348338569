"""Reading run logs back: decoded messages per topic, the run's metadata, a summary for ``info``.

Sim time of a message = log time - the run's epoch (metadata ``run.epoch_ns``). Whatever is
wrong with a file (missing, not an MCAP, truncated, corrupt chunks, undecodable messages, a
foreign or hand-edited log) surfaces as one :class:`LogReadError` naming the file.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory


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
    path: Path
    profile: str
    library: str
    start_s: float
    end_s: float
    messages: int
    topics: list[TopicInfo]
    metadata: dict[str, dict[str, str]]
    attachments: list[str]


def _open(path: str | Path):
    path = Path(path)
    if not path.is_file():
        raise LogReadError(f"{path}: no such file")
    return path, open(path, "rb")


def read_info(path: str | Path) -> LogInfo:
    """Summary of a finished log (topics, counts, time span, metadata)."""
    path, f = _open(path)
    with f, _reading(path, "not a readable MCAP file"):
        reader = make_reader(f)
        header = reader.get_header()
        summary = reader.get_summary()
        if summary is None:
            raise LogReadError(f"{path}: the MCAP has no summary (the run was killed before it could finish the file)")
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
        path=path,
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
    with f, _reading(path, "damaged MCAP"):
        for a in make_reader(f).iter_attachments():
            if a.name == name:
                return a.data
    return None


def read_attached_scenario(path: str | Path):
    """The validated scenario attached to a run log (``scenario.toml``), or None if there is
    none; ScenarioError if it no longer validates."""
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
    return parse_scenario(parse_toml(text, source, ScenarioError), source)


def iter_messages(path: str | Path, topics: list[str] | None = None) -> Iterator[tuple[str, float, Any]]:
    """(topic, sim time [s], decoded message) in log-time order; JSON decodes to dicts,
    protobuf to message objects."""
    path, f = _open(path)
    with f, _reading(path, "damaged MCAP"):
        reader = make_reader(f)
        meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        epoch = _epoch(path, meta)
        factory = DecoderFactory()  # per file: it caches decoders by schema id
        decoders: dict[int, Any] = {}
        for schema, channel, message in reader.iter_messages(topics=topics, log_time_order=True):
            if channel.message_encoding == "json":
                decoded = json.loads(message.data)
            else:
                dec = decoders.get(schema.id) if schema is not None else None
                if dec is None:
                    dec = factory.decoder_for(channel.message_encoding, schema)
                    if dec is None:
                        raise LogReadError(f"{path}: {channel.topic}: no decoder for {channel.message_encoding!r}")
                    decoders[schema.id] = dec
                decoded = dec(message.data)
            yield channel.topic, (message.log_time - epoch) / 1e9, decoded


def _epoch(path: Path, meta: dict[str, dict[str, str]]) -> int:
    """Log time of sim time 0 [ns]: metadata ``run.epoch_ns`` (0 without it)."""
    try:
        return int(meta.get("run", {}).get("epoch_ns", 0))
    except ValueError:
        raise LogReadError(f"{path}: metadata run.epoch_ns is not an integer") from None


def read_topic(path: str | Path, topic: str) -> list[tuple[float, Any]]:
    """All messages of one topic as (sim time [s], decoded)."""
    return [(t, m) for _, t, m in iter_messages(path, [topic])]
