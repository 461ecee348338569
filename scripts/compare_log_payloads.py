"""Compare two MCAP run logs channel by channel: are their message payloads byte-identical?

    python scripts/compare_log_payloads.py A.mcap B.mcap

For every topic in either log: message counts, and whether every (log time, payload) pair is
identical in order. Wall-clock timings differ by nature: a channel that names its wall-clock
fields (metadata ``wallclock_fields``, dotted paths) is judged without them; one marked
``wallclock=true`` without such a list (planner latency) is reported but not judged; logs written
before channels were marked have their planners' timing fields (:data:`LEGACY_WALLCLOCK_KEYS`)
removed wherever they stand. Every other byte counts. Exit 0 when every judged channel is
identical, 1 otherwise.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path
from typing import Any

from mcap.reader import make_reader

# wall-clock timings [s or ms] inside planner records of unmarked (older) logs:
# ``diagnostics.runtime_ms`` of reach-set plans, ``runtime_s`` of reach-set decisions,
# ``diagnostics.runtime_s``/``weather_s`` of MPTP plans
LEGACY_WALLCLOCK_KEYS = frozenset({"runtime_ms", "runtime_s", "weather_s"})


def _without_keys(value: Any, keys: frozenset[str]) -> Any:
    if isinstance(value, dict):
        return {k: _without_keys(v, keys) for k, v in value.items() if k not in keys}
    if isinstance(value, list):
        return [_without_keys(v, keys) for v in value]
    return value


def _without_paths(value: Any, paths: list[list[str]]) -> Any:
    for path in paths:
        node = value
        for key in path[:-1]:
            node = node.get(key) if isinstance(node, dict) else None
        if isinstance(node, dict):
            node.pop(path[-1], None)
    return value


def _payload(encoding: str, data: bytes, metadata: dict[str, str]) -> bytes:
    if encoding != "json":
        return data
    value = json.loads(data)
    if "wallclock_fields" in metadata:
        value = _without_paths(value, [p.split(".") for p in metadata["wallclock_fields"].split(",") if p])
    else:
        value = _without_keys(value, LEGACY_WALLCLOCK_KEYS)
    return json.dumps(value, sort_keys=True).encode()


def channel_digests(path: Path) -> dict[str, tuple[int, str, bool]]:
    """topic -> (message count, SHA-256 over (log time, payload) in log order, wall-clock?)."""
    hashes: dict[str, hashlib._Hash] = {}
    counts: dict[str, int] = {}
    wall: dict[str, bool] = {}
    with path.open("rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages(log_time_order=True):
            h = hashes.setdefault(channel.topic, hashlib.sha256())
            h.update(message.log_time.to_bytes(8, "little"))
            data = _payload(channel.message_encoding, message.data, channel.metadata)
            h.update(len(data).to_bytes(8, "little"))
            h.update(data)
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            # judged unless it is wall-clock through and through (no list of its wall-clock fields)
            wall[channel.topic] = (
                channel.metadata.get("wallclock") == "true" and "wallclock_fields" not in channel.metadata
            )
    return {t: (counts[t], hashes[t].hexdigest(), wall[t]) for t in hashes}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("a", type=Path)
    ap.add_argument("b", type=Path)
    args = ap.parse_args(argv)
    da, db = channel_digests(args.a), channel_digests(args.b)
    differ = 0
    for topic in sorted(da.keys() | db.keys()):
        ca, ha, wa = da.get(topic, (0, "", False))
        cb, hb, wb = db.get(topic, (0, "", False))
        if wa or wb:
            verdict = "wall-clock (not judged)"
        elif ha == hb:
            verdict = "identical"
        else:
            verdict = "DIFFERENT"
            differ += 1
        print(f"{topic:45s} {ca:7d} {cb:7d}  {verdict}")
    judged = sum(1 for t in da.keys() | db.keys() if not (da.get(t, (0, "", False))[2] or db.get(t, (0, "", False))[2]))
    print(f"{judged - differ} of {judged} channels identical ({args.a.name} vs {args.b.name})")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
