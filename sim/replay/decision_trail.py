"""The decision trail of a run's rules of the air and UTM authority, for the Markdown report:
what the authority decided (cases from open to close, roundabouts, weather cases, mandates and
forged cases sent, vehicles without acknowledgement, links lost and regained, breaches) and what
every rules vehicle decided (its ``rule:*`` events: cases, merges with the directives,
cooperative / response / blind mode, claims and acknowledgements of response mode, mandates
obeyed, manoeuvres; not the restrictions a manoeuvre is made of), each as one row
from the first to the last consecutive frame it held in. Read from the ``/utm/*`` topics and
the vehicles' ``/<vehicle>/plan/decision`` events; sim seconds.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from sim.mcap_read import LogInfo
from sim.replay.log_stream import log_vehicles
from sim.replay.runlog import RunLog

Row = tuple[float, float | None, str, str]  # from [s], until [s] (None: an instant), who, decision

# written with every manoeuvre frame, the restrictions a manoeuvre is made of: not decisions of their own
_PARTS = ("rule:resolution", "rule:right_plane_heading:", "rule:safety_margin:", "rule:widest:")


def streaks(frames: Iterable[tuple[float, set[str]]], who: str) -> list[Row]:
    """One row per run of consecutive frames (time, items) an item is in."""
    start: dict[str, float] = {}
    out: list[Row] = []
    last = 0.0
    for t, items in frames:
        for k in [k for k in start if k not in items]:
            out.append((start.pop(k), last, who, k))
        for k in sorted(items):
            start.setdefault(k, t)
        last = t
    return out + [(s, last, who, k) for k, s in start.items()]


def _case(c: dict) -> str:
    a, b = c["ids"]
    ra, rb = c["roles"]
    return f"case {a}-{b} {c['encounter']}: {a} {ra}, {b} {rb}, margin {c['margin_m']:.0f} m"


def _who(m: dict) -> str:
    """The authority that wrote a ``/utm`` message: ``utm``, or ``utm <cluster>`` with clusters."""
    c = m.get("cluster", "all")
    return "utm" if c == "all" else f"utm {c}"


def authority_rows(log: RunLog) -> list[Row]:
    """The authorities' decisions, per airspace cluster (empty without an authority)."""
    if not log.has("/utm/frame"):
        return []
    items: dict[str, dict[float, set[str]]] = {}
    for f in log.topic("/utm/frame").messages:
        now = items.setdefault(_who(f), {})[float(f["t"])] = {_case(c) for c in f["active"]}
        now |= {f"roundabout {'-'.join(r['members'])}, margin {r['margin_m']:.0f} m" for r in f["roundabouts"]}
        now |= {f"no acknowledgement from {v}" for v in f["unacknowledged"]}
    for d in log.topic("/utm/directive").messages:  # sent at the frame time
        now = items[_who(d)][float(d["t"])]
        now |= {f"weather case {w['id']} to {d['to']}" for w in d.get("weather", [])}
        now |= {f"mandate {m['id']} to {d['to']}" for m in d.get("mandates", [])}
        if _who(d) != "utm":  # with clusters: which authority directs whom (the hand-overs)
            now.add(f"directs {d['to']}")
    for m in log.topic("/utm/spoof").messages if log.has("/utm/spoof") else []:
        items[_who(m)][float(m["t"])].add(f"forged case {m['case']['ids'][1]} to {m['to']}")
    rows = [r for who, frames in items.items() for r in streaks(sorted(frames.items()), who)]
    for m in log.topic("/utm/link").messages if log.has("/utm/link") else []:
        rows.append((float(m["t"]), None, _who(m), f"link to {m['vehicle']} {m['state']}"))
    for m in log.topic("/utm/breach").messages if log.has("/utm/breach") else []:
        what = f"mandate {m['mandate']['id']} by {m['vehicle']}" if "mandate" in m else _case(m["case"])
        rows.append((float(m["t"]), None, _who(m), f"breach of {what}"))
    return rows


def vehicle_rows(log: RunLog, vehicle: str) -> list[Row]:
    """A rules vehicle's ``rule:*`` decisions."""
    dec = log.topic(f"/{vehicle}/plan/decision")
    frames = (
        (float(t), {e for e in m["events"] if e.startswith("rule:") and not e.startswith(_PARTS)})
        for t, m in zip(dec.t, dec.messages, strict=True)
    )
    return streaks(frames, vehicle)


def trail_markdown(path: Path, info: LogInfo) -> list[str]:
    """The report section (no lines when the run has neither an authority nor rules vehicles),
    read from the log at ``path`` (summary ``info``): only the topics the trail reads."""
    have = {ti.topic for ti in info.topics}
    rules = [v for v in log_vehicles(info) if f"/{v}/plan/rules" in have]
    topics = [t for t in have if t.startswith("/utm/")] + [f"/{v}/plan/decision" for v in rules]
    if not topics:
        return []
    log = RunLog(path, [t for t in topics if t in have])
    rows = authority_rows(log) + [r for v in rules for r in vehicle_rows(log, v)]
    if not rows:
        return []
    lines = ["## Decision trail", "", "| from [s] | until [s] | who | decision |", "|---|---|---|---|"]
    for start, end, who, what in sorted(rows, key=lambda r: (r[0], r[2], r[3])):
        until = "" if end is None else f"{end:.1f}"
        lines.append(f"| {start:.1f} | {until} | {who} | {what} |")
    return [*lines, ""]
