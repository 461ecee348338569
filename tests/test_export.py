"""Analysis API and export: RunLog.frame, cosim export (Parquet, CSV), the shipped Foxglove layout."""

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sim.replay.frame import INDEX, as_dict, flatten_message
from sim.replay.runlog import RunLog

ROOT = Path(__file__).resolve().parents[1]
LAYOUT = ROOT / "docs" / "foxglove" / "cosim_layout.json"


@pytest.fixture(scope="module")
def mixed(fly_in, tmp_path_factory):
    """The shipped HAPS + quadrotor scenario flown 5 s: JSON, protobuf and nested topics."""
    return fly_in(tmp_path_factory.mktemp("export"), "mixed_haps_quad", "mixed", duration=5.0).path


def _cell(message: dict, column: str):
    """A frame column read straight from the decoded message: dotted keys, list indices."""
    node = message
    for key in column.split("."):
        node = node[int(key)] if isinstance(node, list) else node[key]
    return json.dumps(node, separators=(",", ":")) if isinstance(node, list) else node


@pytest.fixture(scope="module")
def parquet_dir(mixed, tmp_path_factory, cosim) -> Path:
    """Every topic of ``mixed`` exported to Parquet by one ``cosim export`` run."""
    out = tmp_path_factory.mktemp("parquet")
    proc = cosim("export", mixed, "--format", "parquet", "-o", out, "-q")
    assert proc.returncode == 0, proc.stderr
    return out


def test_parquet_export_writes_one_file_per_topic(mixed, parquet_dir):
    expected = {t.strip("/").replace("/", ".") + ".parquet" for t in RunLog(mixed).topics}
    assert {f.name for f in parquet_dir.iterdir()} == expected


@pytest.mark.parametrize("topic", ["/haps/truth/state", "/haps/energy", "/quad/ctrl/commands", "/tf", "/log"])
def test_parquet_export_equals_the_logged_messages(mixed, parquet_dir, topic):
    df = pd.read_parquet(parquet_dir / (topic.strip("/").replace("/", ".") + ".parquet"))
    series = RunLog(mixed).topic(topic)
    assert df.index.name == INDEX and np.array_equal(df.index.to_numpy(), series.t)  # sim time [s]
    messages = [as_dict(m) for m in series.messages]
    assert set(df.columns) == set().union(*(flatten_message(m) for m in messages))
    for i, m in enumerate(messages):
        for col in flatten_message(m):
            assert df[col].iloc[i] == _cell(m, col), (i, col)  # exact, floats bit for bit


def test_frame_flattens_nested_fields_under_a_sim_time_index(mixed):
    log = RunLog(mixed)
    st = log.frame("/haps/truth/state")
    assert list(st.columns[:4]) == ["t", "pos_ned.0", "pos_ned.1", "pos_ned.2"]
    assert np.array_equal(st["pos_ned.2"].to_numpy(), log.topic("/haps/truth/state")["pos_ned"][:, 2])
    assert st.index.name == INDEX and st.index[1] == pytest.approx(0.1)
    energy = log.frame("/haps/energy")
    assert "cumulative_wh.solar" in energy.columns  # nested object
    plan = log.frame("/haps/plan")
    assert json.loads(plan["positions"].iloc[0])[1] == log.topic("/haps/plan").messages[0]["positions"][1]
    loc = log.frame("/haps/truth/location")  # protobuf: fields by name, timestamps in seconds
    assert loc["latitude"].iloc[0] == pytest.approx(47.0) and loc["timestamp"].iloc[0] > 1.7e9


def test_csv_export_and_its_errors(mixed, tmp_path, cosim):
    out = tmp_path / "csv"
    proc = cosim("export", mixed, "--format", "csv", "--topics", "/haps/truth/state", "/log", "-o", out, "-q")
    assert proc.returncode == 0, proc.stderr
    assert sorted(f.name for f in out.iterdir()) == ["haps.truth.state.csv", "log.csv"]
    back = pd.read_csv(out / "haps.truth.state.csv", index_col=INDEX)
    st = RunLog(mixed).frame("/haps/truth/state")
    assert np.array_equal(back["pos_ned.0"].to_numpy(), st["pos_ned.0"].to_numpy())  # shortest repr round-trips
    bad = cosim("export", mixed, "--format", "csv", "--topics", "/haps/nope", "-o", tmp_path / "x")
    assert bad.returncode == 2 and "no topic '/haps/nope'" in bad.stderr and "/haps/truth/state" in bad.stderr
    assert not (tmp_path / "x").exists()
    fmt = cosim("export", mixed, "--format", "xlsx")
    assert fmt.returncode == 2 and "invalid choice: 'xlsx'" in fmt.stderr


def _layout_references(layout: dict) -> tuple[set[str], list[str], set[str]]:
    """(topics, plot message paths, 3D frames) the layout names."""
    topics: set[str] = set()
    paths: list[str] = []
    frames: set[str] = set()
    for panel_id, cfg in layout["configById"].items():
        kind = panel_id.split("!")[0]
        if kind == "Plot":
            paths += [p["value"] for p in cfg["paths"]]
        elif kind == "Map":
            topics |= set(cfg["topicColors"]) | {cfg["followTopic"]}
        elif kind == "3D":
            topics |= set(cfg["topics"])
            frames |= {cfg["followTf"], cfg["layers"]["grid"]["frameId"]}
        elif kind == "RosOut":
            topics.add(cfg["topicToRender"])
        else:
            raise AssertionError(f"the test does not know panel {panel_id}")
    return topics, paths, frames


_PATH = re.compile(r"^(/[A-Za-z0-9_/]+)\.(.+)$")


def test_foxglove_layout_names_only_topics_and_fields_of_a_real_log(mixed):
    layout = json.loads(LAYOUT.read_text())
    log = RunLog(mixed)
    topics, paths, frames = _layout_references(layout)
    kinds = {p.split("!")[0] for p in layout["configById"]}
    assert {"Map", "3D", "Plot", "RosOut"} <= kinds and len(paths) >= 15
    missing = sorted(t for t in topics if not log.has(t))
    for p in paths:
        m = _PATH.match(p)
        assert m, f"not a message path: {p}"
        topic, fields = m.groups()
        if not log.has(topic):
            missing.append(topic)
            continue
        column = re.sub(r"\[(\d+)\]", r".\1", fields)
        assert column in log.frame(topic).columns, f"{p}: no field {fields!r} on {topic}"
    assert missing == []
    tf = {t["child_frame_id"] for m in log.topic("/tf").messages for t in as_dict(m)["transforms"]}
    tf |= {t["parent_frame_id"] for m in log.topic("/tf").messages for t in as_dict(m)["transforms"]}
    assert frames <= tf, frames - tf
    titles = " ".join(c.get("title", "") for c in layout["configById"].values())
    for plot in ("altitude", "airspeed", "attitude", "cross-track", "separation"):
        assert plot in titles


def test_export_reports_progress_in_messages(mixed, tmp_path):
    from sim.mcap_read import read_info
    from sim.replay.export import export_log

    calls: list[tuple[int, int]] = []
    export_log(mixed, tmp_path, "csv", ["/haps/truth/state", "/tf"], lambda k, total: calls.append((k, total)))
    counts = {ti.topic: ti.count for ti in read_info(mixed).topics}
    total = 2 * (counts["/haps/truth/state"] + counts["/tf"])  # read twice: columns, then rows
    assert calls and calls[-1] == (total, total) and all(t == total for _, t in calls)


@pytest.mark.parametrize("fmt", ["parquet", "csv"])
def test_export_in_small_batches_equals_the_whole_topic_table(mixed, tmp_path, fmt):
    """Written 7 rows at a time, every topic's file holds what the whole-topic table writes:
    the same columns in the same order, the same types (integers with gaps as floats, text and
    flags with gaps nullable), the same values; CSV byte for byte."""
    from sim.replay.export import export_log, topic_file

    log = RunLog(mixed)
    files = export_log(mixed, tmp_path / "streamed", fmt, batch=7)
    assert len(files) == len(log.topics)
    whole_dir = tmp_path / "whole"
    whole_dir.mkdir()
    for topic in log.topics:
        whole = whole_dir / topic_file(topic, fmt)
        streamed = tmp_path / "streamed" / topic_file(topic, fmt)
        if fmt == "csv":
            log.frame(topic).to_csv(whole)
            assert streamed.read_text() == whole.read_text(), topic
        else:
            log.frame(topic).to_parquet(whole)
            pd.testing.assert_frame_equal(pd.read_parquet(streamed), pd.read_parquet(whole), obj=topic)


def test_export_column_types_follow_the_whole_topic():
    """A column's type is decided over every row, not per batch."""
    from sim.replay.export import _Columns

    cols = _Columns()
    for row in ({"a": 1, "b": True, "c": "x", "d": 2}, {"a": 2.5, "b": None, "d": 3}, {"a": 3, "c": None, "d": 4}):
        cols.add(row)
    assert [cols.dtype(n) for n in "abcd"] == ["float64", "object", "object", "int64"]
    assert [str(cols.arrow_type(n)) for n in "abcd"] == ["double", "bool", "string", "int64"]
    cols.add({"e": "text"})
    cols.add({"e": 1.0})
    with pytest.raises(ValueError, match="column 'e' mixes float, str"):
        cols.arrow_type("e")


@pytest.mark.parametrize("fmt", ["parquet", "csv"])
def test_topic_writer_gives_batches_the_whole_topic_types(tmp_path, fmt):
    """Batches of 2 rows where the gaps fall in the last batch only: the first batch's integers
    and flags are written as the whole table has them (floats, nullable flags)."""
    from sim.replay.export import _Columns, _TopicWriter
    from sim.replay.frame import frame

    rows = [{"a": 1, "b": True, "s": "x"}, {"a": 2, "b": False, "s": "y"}, {"a": None, "s": "z"}, {"b": True}]
    times = [0.0, 0.1, 0.2, 0.30000000000000004]
    cols = _Columns()
    for r in rows:
        cols.add(r)
    writer = _TopicWriter(tmp_path / f"t.{fmt}", fmt, cols, batch=2)
    for t, r in zip(times, rows, strict=True):
        writer.add(t, r)
    writer.close()
    whole = tmp_path / f"whole.{fmt}"
    if fmt == "csv":
        frame(times, rows).to_csv(whole)
        assert (tmp_path / "t.csv").read_text() == whole.read_text()
        assert (tmp_path / "t.csv").read_text().splitlines()[1] == "0.0,1.0,True,x"
    else:
        frame(times, rows).to_parquet(whole)
        pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "t.parquet"), pd.read_parquet(whole))
