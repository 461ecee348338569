"""Do two code trees fly a shipped scenario to the same log? (performance changes must not change
results)

Flies ``scenarios/<SCENARIO>.toml`` for ``--sim-seconds`` with each tree (a checkout or an
exported commit, each in its own process, importing its own ``sim``) and compares the MCAP
payloads topic by topic: identical bytes, or, on the channels marked ``wallclock=true``, identical
JSON once their ``wallclock_fields`` are removed (as ``tests/test_log_contracts.py`` compares two
runs of one tree). Prints one line per scenario and exits 1 when a topic differs otherwise.

``--rtol R --atol A`` (tolerance mode, for changes that reorder floating-point arithmetic): a
topic whose bytes differ is decoded (``sim.mcap_read``) and passes when both logs hold the same
messages at the same log times with the same fields, equal strings and booleans, and every number
within ``A + R * max(|a|, |b|)`` (NaN equals NaN); each such topic's largest difference is
printed with its field, its relative size and the size of the field's values. ``--ulp-floor``
also flies the reference tree with every EKF's gravity one unit in the last place larger and
compares it with the reference the same way: how far the same code's logs move when one bit of
the estimator moves (the closed loop carries such a change into every vehicle state), the scale
against which the differences of a reordered arithmetic are judged.

    git archive <commit> | tar -x -C /tmp/before
    python benchmarks/same_logs.py /tmp/before . mixed_haps_quad_reachset reachset_fleet8 --sim-seconds 30
    python benchmarks/same_logs.py /tmp/before . mixed_haps_quad_reachset --rtol 0 --atol 0.01 --ulp-floor
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from google.protobuf.json_format import MessageToDict
from mcap.reader import make_reader

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sim.mcap_read import iter_messages  # noqa: E402

FLY = """
import math, sys, tomllib
from pathlib import Path
sys.path.insert(0, ".")
import sim.estimation.sensor_estimator as se
from sim.runner import run_scenario
from sim.scenario import parse_scenario
name, seconds, out, ulp = sys.argv[1], float(sys.argv[2]), sys.argv[3], sys.argv[4] == "1"
if ulp:  # every EKF's gravity one unit in the last place larger
    g = se.normal_gravity
    se.normal_gravity = lambda lat, alt: math.nextafter(g(lat, alt), math.inf)
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


@dataclass
class Worst:
    """A topic's largest numeric difference: |a - b|, the field, |a - b| / max(|a|, |b|), the
    largest |value| of that field in the topic."""

    diff: float = 0.0
    field: str = ""
    rel: float = 0.0
    scale: float = 0.0


def _leaves(msg: Any, prefix: str = "") -> Iterator[tuple[str, Any]]:
    """(dotted field, value) of every leaf of a decoded message (list items by index)."""
    if hasattr(msg, "DESCRIPTOR"):  # Foxglove protobuf types
        msg = MessageToDict(msg, preserving_proto_field_name=True)
    if isinstance(msg, dict):
        for k, v in msg.items():
            yield from _leaves(v, f"{prefix}.{k}" if prefix else str(k))
    elif isinstance(msg, list):
        for i, v in enumerate(msg):
            yield from _leaves(v, f"{prefix}[{i}]")
    else:
        yield prefix, msg


def _number(v: Any) -> float | None:
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else None


def _under(field: str, roots: list[str]) -> bool:
    """Whether ``field`` is one of ``roots`` or inside one (a member or a list item)."""
    return any(field == r or field.startswith((r + ".", r + "[")) for r in roots)


def within(a: Path, b: Path, topic: str, wallclock: list[str], rtol: float, atol: float) -> Worst | str:
    """How ``topic`` differs between logs ``a`` and ``b`` beyond the wall-clock fields: its
    largest difference when every number is within the tolerance, else the first failure."""
    ma = [(t, dict(_leaves(m))) for _, t, m in iter_messages(a, [topic])]
    mb = [(t, dict(_leaves(m))) for _, t, m in iter_messages(b, [topic])]
    if len(ma) != len(mb):
        return f"{len(ma)} messages against {len(mb)}"
    worst = Worst()
    scales: dict[str, float] = {}
    for (ta, fa), (tb, fb) in zip(ma, mb, strict=True):
        if ta != tb:
            return f"log time {ta!r} against {tb!r}"
        for fields in (fa, fb):
            for f in [f for f in fields if _under(f, wallclock)]:
                del fields[f]
        if fa.keys() != fb.keys():
            return f"t={ta:g}: fields {sorted(fa.keys() ^ fb.keys())[:3]} in one log only"
        for field, va in fa.items():
            vb = fb[field]
            xa, xb = _number(va), _number(vb)
            if xa is None or xb is None:
                if va != vb:
                    return f"t={ta:g}: {field} {va!r} against {vb!r}"
                continue
            size = max(abs(xa), abs(xb))
            if math.isfinite(size):
                scales[field] = max(scales.get(field, 0.0), size)
            if xa == xb or (math.isnan(xa) and math.isnan(xb)):
                continue
            d = abs(xa - xb)
            if not d <= atol + rtol * size:
                return f"t={ta:g}: {field} {xa!r} against {xb!r}"
            if d > worst.diff:
                worst = Worst(d, field, d / size, 0.0)
    worst.scale = scales.get(worst.field, 0.0)
    return worst


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("before", type=Path, help="the reference code tree")
    ap.add_argument("after", type=Path, help="the code tree under test")
    ap.add_argument("scenarios", nargs="+", help="shipped scenario names (scenarios/<name>.toml)")
    ap.add_argument("--sim-seconds", type=float, default=30.0)
    ap.add_argument("--rtol", type=float, default=None, help="tolerance mode: relative tolerance")
    ap.add_argument("--atol", type=float, default=0.0, help="tolerance mode: absolute tolerance")
    ap.add_argument("--ulp-floor", action="store_true", help="tolerance mode: the reference against itself, 1 ulp off")
    args = ap.parse_args()
    failed = False
    with tempfile.TemporaryDirectory() as d:
        for name in args.scenarios:
            runs = [(args.before, "0"), (args.after, "0")] + ([(args.before, "1")] if args.ulp_floor else [])
            logs = []
            for k, (tree, ulp) in enumerate(runs):
                log = Path(d) / f"{Path(name).name}_{k}.mcap"
                cmd = [sys.executable, "-c", FLY, name, str(args.sim_seconds), str(log), ulp]
                subprocess.run(cmd, cwd=tree.resolve(), check=True)
                logs.append(log)
            if args.rtol is None:
                n, bad = differing_topics(*logs[:2])
                failed |= bool(bad)
                verdict = "same log" if not bad else f"DIFFERENT: {bad}"
                print(f"{name} ({args.sim_seconds:g} s): {n} topics, {verdict}")
                continue
            failed |= compare(name, logs[0], logs[1], args.rtol, args.atol, f"{args.sim_seconds:g} s")
            if args.ulp_floor:
                compare(name, logs[0], logs[2], args.rtol, args.atol, "the reference 1 ulp off")
    sys.exit(1 if failed else 0)


def compare(name: str, a: Path, b: Path, rtol: float, atol: float, what: str) -> bool:
    """Print how the logs ``a`` and ``b`` differ, topic by topic; True when beyond tolerance."""
    n, bad = differing_topics(a, b)
    print(f"{name} ({what}): {n} topics, {n - len(bad)} identical")
    meta = channels(a)
    failed = False
    for topic in bad:
        m = meta.get(topic, ({}, []))[0]
        wall = m.get("wallclock_fields", "").split(",") if m.get("wallclock") == "true" else []
        res = within(a, b, topic, wall, rtol, atol) if topic in meta else "in one log only"
        failed |= isinstance(res, str)
        if isinstance(res, str):
            print(f"  {topic}: DIFFERENT: {res}")
        else:
            where = f"{res.field} ({res.rel:.2g} of it; values up to {res.scale:.3g})"
            print(f"  {topic}: within, largest {res.diff:.3g} in {where}")
    return failed


if __name__ == "__main__":
    main()
