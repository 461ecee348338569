"""Do two code trees fly a shipped scenario to the same log? (performance changes must not change
results)

Flies ``scenarios/<SCENARIO>.toml`` for ``--sim-seconds`` with each tree (a checkout or an
exported commit, each in its own process, importing its own ``sim``) and compares the MCAP
payloads topic by topic: identical bytes, or, on the channels marked ``wallclock=true``, identical
JSON once their ``wallclock_fields`` are removed (as ``tests/test_log_contracts.py`` compares two
runs of one tree). Prints one line per scenario and exits 1 when a topic differs otherwise.

    git archive <commit> | tar -x -C /tmp/before
    python benchmarks/same_logs.py /tmp/before . mixed_haps_quad_reachset reachset_fleet8 --sim-seconds 30
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from mcap.reader import make_reader

FLY = """
import sys, tomllib
from pathlib import Path
sys.path.insert(0, ".")
from sim.runner import run_scenario
from sim.scenario import parse_scenario
name, seconds, out = sys.argv[1], float(sys.argv[2]), sys.argv[3]
data = tomllib.loads(Path("scenarios", name + ".toml").read_text())
run_scenario(parse_scenario(data, name), out, duration=seconds)
"""


def channels(path: Path) -> dict[str, tuple[dict[str, str], list[bytes]]]:
    """topic -> (channel metadata, payloads in log-time order)."""
    out: dict[str, tuple[dict[str, str], list[bytes]]] = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None, f"{path}: no summary"
        for ch in summary.channels.values():
            out[ch.topic] = (dict(ch.metadata), [])
        for _, ch, msg in reader.iter_messages(log_time_order=True):
            out[ch.topic][1].append(msg.data)
    return out


def _without_wallclock(payloads: list[bytes], fields: list[str]) -> list[dict]:
    out = []
    for p in payloads:
        m = json.loads(p)
        for dotted in fields:
            *parents, leaf = dotted.split(".")
            obj = m
            for key in parents:
                obj = obj.get(key, {})
            obj.pop(leaf, None)
        out.append(m)
    return out


def differing_topics(a: Path, b: Path) -> tuple[int, list[str]]:
    """(number of topics compared, topics whose payloads differ beyond their wall-clock fields)."""
    ca, cb = channels(a), channels(b)
    bad = sorted(set(ca) ^ set(cb))
    for topic in sorted(set(ca) & set(cb)):
        meta, pa = ca[topic]
        pb = cb[topic][1]
        if pa == pb:
            continue
        fields = meta.get("wallclock_fields", "").split(",") if meta.get("wallclock") == "true" else []
        if not fields or _without_wallclock(pa, fields) != _without_wallclock(pb, fields):
            bad.append(topic)
    return len(set(ca) | set(cb)), bad


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("before", type=Path, help="the reference code tree")
    ap.add_argument("after", type=Path, help="the code tree under test")
    ap.add_argument("scenarios", nargs="+", help="shipped scenario names (scenarios/<name>.toml)")
    ap.add_argument("--sim-seconds", type=float, default=30.0)
    args = ap.parse_args()
    failed = False
    with tempfile.TemporaryDirectory() as d:
        for name in args.scenarios:
            logs = []
            for k, tree in enumerate((args.before, args.after)):
                log = Path(d) / f"{Path(name).name}_{k}.mcap"
                cmd = [sys.executable, "-c", FLY, name, str(args.sim_seconds), str(log)]
                subprocess.run(cmd, cwd=tree.resolve(), check=True)
                logs.append(log)
            n, bad = differing_topics(*logs)
            failed |= bool(bad)
            verdict = "same log" if not bad else f"DIFFERENT: {bad}"
            print(f"{name} ({args.sim_seconds:g} s): {n} topics, {verdict}")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
