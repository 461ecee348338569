"""Logs keep their own contracts, on short runs of the shipped scenarios (each planner, both
airframe kinds): every JSON message validates against the JSON Schema of its channel, and two
runs of the same scenario and seed log byte-identical payloads except in the fields their
channel marks as wall clock (``wallclock=true``, ``wallclock_fields``)."""

import json
import tomllib
from collections import defaultdict
from pathlib import Path

import jsonschema
import pytest
from mcap.reader import make_reader

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
    ("mptp/storm_crossing.toml", 120.0),
    ("quad_motor_failure.toml", 10.0),  # ends in a crash (/world/crash)
]


def _channels(path: Path) -> dict[str, tuple[dict, dict, list]]:
    """topic -> (channel metadata, JSON schema or {}, payloads) of every channel of the log."""
    out: dict[str, tuple[dict, dict, list]] = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        for ch in summary.channels.values():
            schema = summary.schemas.get(ch.schema_id)
            js = json.loads(schema.data) if ch.message_encoding == "json" else {}
            out[ch.topic] = (dict(ch.metadata), js, [])
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
    for topic, (_, schema, payloads) in two_runs[0].items():
        if not schema:
            continue
        validator = jsonschema.Draft202012Validator(schema)
        for data in payloads:
            for err in validator.iter_errors(json.loads(data)):
                bad[topic].append(f"{'/'.join(map(str, err.absolute_path))}: {err.message}")
    assert not bad, {t: sorted(set(e))[:5] for t, e in bad.items()}


def _without(obj: dict, dotted: str) -> None:
    *parents, leaf = dotted.split(".")
    for key in parents:
        obj = obj.get(key, {})
    obj.pop(leaf, None)


def test_only_marked_wall_clock_fields_differ_between_runs(two_runs):
    a, b = two_runs
    assert a.keys() == b.keys()
    unmarked, residue = [], []
    for topic, (meta, _, pa) in a.items():
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
