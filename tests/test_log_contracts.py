"""Logs keep their own contracts, on short runs of the shipped scenarios (each planner, both
airframe kinds, a LiDAR): every JSON message validates against the JSON Schema of its channel;
every cosim protobuf message decodes with its channel's schema (the log's own descriptors) into
every field of the JSON Schema of the same title, and validates against it; two runs of the same
scenario and seed log byte-identical payloads except in the fields their channel marks as wall
clock (``wallclock=true``, ``wallclock_fields``)."""

import json
import tomllib
from collections import defaultdict
from pathlib import Path
from typing import Any

import jsonschema
import pytest
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from sim import log_schemas as S
from sim.log_proto import record_dict
from sim.runner import run_scenario
from sim.scenario import parse_scenario

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.closed_loop

# (scenario, sim time [s]): fixed wing, multirotor, geometric, reach-set, rules of the air, MPTP,
# a crash
SCENARIOS = [
    ("haps_box_mission.toml", 10.0),
    ("quad_square_mission.toml", 20.0),
    ("geometric/s2_climb_over.toml", 10.0),
    ("reachset/s2_slalom.toml", 10.0),
    ("rules/s10_head_on.toml", 10.0),
    ("rules/s9_converging_utm.toml", 10.0),  # the UTM authority's /utm/* topics
    ("mptp/storm_crossing.toml", 120.0),
    ("reachset/building_lidar.toml", 10.0),
    ("quad_motor_failure.toml", 10.0),  # ends in a crash (/world/crash)
]
JSON_SCHEMAS = {v["title"]: v for v in vars(S).values() if isinstance(v, dict) and "title" in v}


def _channels(path: Path) -> dict[str, tuple[dict, dict, list, Any]]:
    """topic -> (channel metadata, JSON schema or {}, payloads, MCAP schema) of every channel."""
    out: dict[str, tuple[dict, dict, list, Any]] = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        for ch in summary.channels.values():
            schema = summary.schemas.get(ch.schema_id)
            js = json.loads(schema.data) if ch.message_encoding == "json" else {}
            out[ch.topic] = (dict(ch.metadata), js, [], schema)
        for _, ch, msg in reader.iter_messages(log_time_order=True):
            out[ch.topic][2].append(msg.data)
    return out


@pytest.fixture(scope="module", params=SCENARIOS, ids=[s for s, _ in SCENARIOS])
def two_runs(request, tmp_path_factory):
    name, duration = request.param
    data = tomllib.loads((ROOT / "scenarios" / name).read_text())
    out = tmp_path_factory.mktemp(Path(name).stem)
    logs = []
    for k in range(2):
        path = out / f"run{k}.mcap"
        run_scenario(parse_scenario(data, name), path, duration=duration)
        logs.append(_channels(path))
    return logs


def test_every_json_message_matches_its_schema(two_runs):
    bad = defaultdict(list)
    for topic, (_, schema, payloads, _) in two_runs[0].items():
        if not schema:
            continue
        validator = jsonschema.Draft202012Validator(schema)
        for data in payloads:
            for err in validator.iter_errors(json.loads(data)):
                bad[topic].append(f"{'/'.join(map(str, err.absolute_path))}: {err.message}")
    assert not bad, {t: sorted(set(e))[:5] for t, e in bad.items()}


def test_every_protobuf_message_decodes_complete(two_runs):
    """Every cosim protobuf message decodes with the log's schema record into all fields of its
    JSON Schema (a cosim.Sensors message: the sensors that delivered) and validates against it."""
    bad, seen = defaultdict(list), set()
    factory = DecoderFactory()
    for topic, (_, _, payloads, schema) in two_runs[0].items():
        if schema is None or schema.encoding != "protobuf" or not schema.name.startswith("cosim."):
            continue
        seen.add(schema.name)
        js = JSON_SCHEMAS[schema.name]
        validator = jsonschema.Draft202012Validator(js)
        decode = factory.decoder_for("protobuf", schema)
        for data in payloads:
            d = record_dict(decode(data))
            required = {"t"} if schema.name == "cosim.Sensors" else set(js["properties"])
            if not required <= d.keys():
                bad[topic].append(f"fields {sorted(required - d.keys())} missing")
            bad[topic] += [f"{'/'.join(map(str, e.absolute_path))}: {e.message}" for e in validator.iter_errors(d)]
    assert seen, "no cosim protobuf channel in the log"
    assert not any(bad.values()), {t: sorted(set(e))[:5] for t, e in bad.items() if e}


def _without(obj: dict, dotted: str) -> None:
    *parents, leaf = dotted.split(".")
    for key in parents:
        obj = obj.get(key, {})
    obj.pop(leaf, None)


def test_only_marked_wall_clock_fields_differ_between_runs(two_runs):
    a, b = two_runs
    assert a.keys() == b.keys()
    unmarked, residue = [], []
    for topic, (meta, _, pa, _) in a.items():
        pb = b[topic][2]
        if pa == pb:
            continue
        if meta.get("wallclock") != "true":
            unmarked.append(topic)
            continue
        fields = meta["wallclock_fields"].split(",")
        ma, mb = [json.loads(x) for x in pa], [json.loads(x) for x in pb]
        for m in ma + mb:
            for f in fields:
                _without(m, f)
        if ma != mb:
            residue.append(topic)
    assert not unmarked, f"channels differ run to run without a wallclock mark: {unmarked}"
    assert not residue, f"channels differ beyond their wallclock_fields: {residue}"
