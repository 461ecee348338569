"""Messages of an indexed MCAP in log-time order, chunk by chunk.

The order is the MCAP library's ``log_time_order``: by log time, ties by position in the file
(chunk offset, then record index in the chunk). The library merges every message through a heap
of Python objects. Here the chunks are read in the order of their first log time; after each, the
messages read so far that are earlier than the next chunk's first log time are final (no later
chunk holds an earlier one) and are yielded in (log time, chunk offset, index) order, sorted with
tuple keys. cosim's writer writes nearly in time order, so few messages wait for the next chunk.
"""

from __future__ import annotations

import bisect
import io
from collections.abc import Iterator
from typing import BinaryIO

from mcap.data_stream import ReadDataStream
from mcap.reader import SeekingReader
from mcap.records import Channel, Chunk, ChunkIndex, Message, Schema
from mcap.stream_reader import breakup_chunk
from mcap.summary import Summary

Item = tuple[Schema | None, Channel, Message]


def _chunk_items(
    f: BinaryIO, summary: Summary, index: ChunkIndex, topics: set[str] | None
) -> list[tuple[int, int, int, Item]]:
    """(log time, chunk offset, record index, item) of the chunk's messages on ``topics`` (all when
    None)."""
    f.seek(index.chunk_start_offset + 1 + 8, io.SEEK_SET)  # past the record's opcode and length
    chunk = Chunk.read(ReadDataStream(f))
    out = []
    for k, record in enumerate(breakup_chunk(chunk, validate_crc=False)):
        if not isinstance(record, Message):
            continue
        channel = summary.channels[record.channel_id]
        if topics is not None and channel.topic not in topics:
            continue
        schema = summary.schemas[channel.schema_id] if channel.schema_id != 0 else None
        out.append((record.log_time, index.chunk_start_offset, k, (schema, channel, record)))
    return out


def _key(entry: tuple[int, int, int, Item]) -> tuple[int, int, int]:
    return entry[0], entry[1], entry[2]


def messages_in_log_time_order(
    reader: SeekingReader, f: BinaryIO, summary: Summary, topics: list[str] | None
) -> Iterator[Item]:
    """(schema, channel, message) of the file ``f`` (read by ``reader``, its ``summary``) on
    ``topics`` (all when None), in the MCAP library's log-time order."""
    if not summary.chunk_indexes:
        yield from reader.iter_messages(topics=topics, log_time_order=True)
        return
    wanted = None if topics is None else set(topics)
    channel_ids = None if wanted is None else {cid for cid, ch in summary.channels.items() if ch.topic in wanted}
    chunks = sorted(
        (
            c
            for c in summary.chunk_indexes
            if channel_ids is None or not c.message_index_offsets or channel_ids & c.message_index_offsets.keys()
        ),
        key=lambda c: (c.message_start_time, c.chunk_start_offset),
    )
    pending: list[tuple[int, int, int, Item]] = []
    for i, index in enumerate(chunks):
        pending += _chunk_items(f, summary, index, wanted)
        pending.sort(key=_key)
        cut = (
            len(pending)
            if i + 1 == len(chunks)
            else bisect.bisect_left(pending, chunks[i + 1].message_start_time, key=lambda e: e[0])
        )
        for entry in pending[:cut]:
            yield entry[3]
        del pending[:cut]
