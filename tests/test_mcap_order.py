"""The chunk-by-chunk log-time order of sim.mcap_order is the MCAP library's ``log_time_order``
(ties by file position), without the library's merge, on files written in time order and on
files written in any order (chunks overlapping in time)."""

import io

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.reader import SeekingReader
from mcap.writer import Writer

from sim import mcap_order

TOPICS = ["/a", "/b", "/c"]


def _mcap(records: list[tuple[int, int]], chunk_size: int) -> io.BytesIO:
    """An MCAP of (topic index, log time [ns]) records written in list order, each message's data
    its position in the list."""
    buf = io.BytesIO()
    w = Writer(buf, chunk_size=chunk_size)
    w.start()
    schema = w.register_schema("s", "jsonschema", b"{}")
    channels = [w.register_channel(t, "json", schema) for t in TOPICS]
    for k, (topic, t) in enumerate(records):
        w.add_message(channels[topic], log_time=t, data=str(k).encode(), publish_time=t)
    w.finish()
    buf.seek(0)
    return buf


def _both(buf: io.BytesIO, topics: list[str] | None) -> tuple[list, list]:
    """(ours, the library's): (topic, log time, data) of each message, in order."""
    reader = SeekingReader(buf)
    summary = reader.get_summary()
    assert summary is not None and summary.chunk_indexes
    theirs = [(c.topic, m.log_time, m.data) for _, c, m in reader.iter_messages(topics=topics, log_time_order=True)]
    with pytest.MonkeyPatch.context() as mp:  # the library's merge is not called
        mp.setattr(SeekingReader, "iter_messages", lambda *a, **k: pytest.fail("merged by the library"))
        ours = [
            (c.topic, m.log_time, m.data)
            for _, c, m in mcap_order.messages_in_log_time_order(reader, buf, summary, topics)
        ]
    return ours, theirs


# time steps of 0 (ties, also across chunk boundaries), small and large; small chunks: many chunks
_steps = st.lists(st.tuples(st.integers(0, 2), st.sampled_from([0, 0, 1, 5, 1000])), min_size=1, max_size=300)


@settings(max_examples=60, deadline=None)
@given(
    steps=_steps,
    chunk_size=st.sampled_from([64, 200, 1000, 1 << 20]),
    topics=st.sampled_from([None, ["/a"], ["/b", "/c"]]),
)
def test_files_written_in_time_order_read_in_the_librarys_order(steps, chunk_size, topics):
    t, records = 10, []
    for topic, dt in steps:
        t += dt
        records.append((topic, t))
    ours, theirs = _both(_mcap(records, chunk_size), topics)
    expected = [
        (TOPICS[k], t, str(i).encode()) for i, (k, t) in enumerate(records) if topics is None or TOPICS[k] in topics
    ]
    assert theirs == expected
    assert ours == expected


@settings(max_examples=60, deadline=None)
@given(
    records=st.lists(st.tuples(st.integers(0, 2), st.integers(0, 50)), min_size=2, max_size=200),
    chunk_size=st.sampled_from([1, 64, 300, 1 << 20]),
    topics=st.sampled_from([None, ["/a", "/c"]]),
)
def test_files_out_of_time_order_read_in_the_librarys_order(records, chunk_size, topics):
    """Log times in any order, within a chunk and across chunks (overlapping in time)."""
    ours, theirs = _both(_mcap(records, chunk_size), topics)
    assert ours == theirs
    assert [t for _, t, _ in ours] == sorted(t for k, t in records if topics is None or TOPICS[k] in topics)


def test_a_chunk_later_in_the_file_with_earlier_messages_is_read_first():
    """One message per chunk (chunk size 1), written at 30, 50, 10 ns: 10 first."""
    ours, theirs = _both(_mcap([(0, 30), (1, 50), (2, 10)], 1), None)
    assert [t for _, t, _ in ours] == [t for _, t, _ in theirs] == [10, 30, 50]
