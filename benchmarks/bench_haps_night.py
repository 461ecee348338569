"""The HAPS's nights in parallel segments: state of charge at dawn (June) and the time the
battery runs empty (December), from the shipped scenarios, in a fraction of a 24 h run's wall time.

A night is cut into consecutive segments flown at the same time in separate interpreters, each
the shipped scenario (same aircraft, energy model, mission, EKF) started at the segment's UTC time
from a trim at station. The battery model is linear in stored energy away from its limits
(``sim/energy/battery.py``: no state-of-charge dependence between empty and full), so the stored
energy of the whole night is the chain: E(t) = E_end(previous segment) + E_segment(t) -
E_segment(start). The chain is valid only where a segment neither fills nor empties its battery;
the script checks that and refuses the result otherwise. What it does not reproduce: the
aircraft's position on the square and the TECS state carried across a segment boundary (a trim
transient of ~1 min per segment).

Cases (``--case``):
- ``june``: ``haps_station_june_47n`` from 17:00 UTC on 21 June (battery full: solar power
  exceeds the consumption until ~18:00 and the day run fills the battery by mid-morning; the
  first segment checks that the battery is full and curtailing at its start) to 05:30 UTC.
- ``june_schedule``: the same night with the altitude schedule: the first segment starts at
  the ceiling (21 km, state ``up``, where the schedule holds the aircraft through the afternoon),
  glides to the 18 km floor once the battery falls to 0.90 and must end there; from then on the
  aircraft flies exactly the plain case (18 km, same speed), so the chain continues with the
  ``june`` segments.
- ``december``: ``haps_station_december_60n`` from its shipped start (06:00 UTC, full) in 3 h
  segments: the time the chained stored energy reaches zero (``energy_depleted``).

    python benchmarks/bench_haps_night.py [--case june|june_schedule|december|all] [--jobs 6]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import tomllib
from concurrent.futures import ThreadPoolExecutor
from datetime import UTC, datetime, timedelta
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sim.mcap_read import read_topic  # noqa: E402

H = 3600.0
JUNE_NIGHT = datetime(2026, 6, 21, 17, 0, tzinfo=UTC)
JUNE_BOUNDS_H = [0.0, 3.5, 6.0, 8.5, 11.0, 12.5]  # after 17:00 UTC: to 05:30 UTC
DECEMBER_BOUNDS_H = [0.0, 3.0, 6.0, 9.0, 12.0, 15.0]  # after the shipped 06:00 UTC start
MID_SOC = 0.7  # start of every chained segment: room to fall ~6 kWh without emptying


def _segment_toml(name: str, start: datetime, hours: float, soc: float, at: tuple[float, float] | None = None) -> dict:
    """The shipped scenario ``name`` as a dict, started at ``start`` for ``hours`` at ``soc``,
    optionally at ``at`` = (altitude [m], true airspeed [m/s]) instead of the shipped ones."""
    data = tomllib.loads((ROOT / "scenarios" / f"{name}.toml").read_text())
    data["start_time"] = start
    data["duration"] = hours * H
    vehicle = data["vehicle"][0]
    vehicle.setdefault("energy", {})["initial_soc"] = soc
    if at is not None:
        vehicle["initial"]["altitude"], vehicle["initial"]["airspeed"] = at
    return data


def _fly(data: dict, out: Path) -> None:
    """Fly the scenario dict in a child interpreter (its own core, its own memory)."""
    code = (
        f"import sys, json, datetime; sys.path.insert(0, {str(ROOT)!r})\n"
        "from sim.runner import run_scenario\n"
        "from sim.scenario import parse_scenario\n"
        "d = json.loads(sys.stdin.read())\n"
        "d['start_time'] = datetime.datetime.fromisoformat(d['start_time'])\n"
        f"run_scenario(parse_scenario(d), {str(out)!r})\n"
    )
    payload = json.dumps({**data, "start_time": data["start_time"].isoformat()})
    proc = subprocess.run([sys.executable, "-c", code], input=payload, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"segment {out.name} failed: {proc.stderr.strip().splitlines()[-1:]}")


def _read(path: Path, start: datetime) -> dict:
    rec = [m for _, m in read_topic(path, "/haps/energy")]
    alt = [m["alt_msl_m"] for _, m in read_topic(path, "/haps/truth/state")]
    return {
        "utc_h": [(start.timestamp() + r["t"]) / H for r in rec],  # POSIX hours
        "energy_wh": [r["energy_wh"] for r in rec],
        "soc": [r["state_of_charge"] for r in rec],
        "sun_deg": [r["sun_elevation_deg"] for r in rec],
        "curtailed_w": [r["curtailed_w"] for r in rec],
        "capacity_wh": rec[0]["energy_wh"] / max(rec[0]["state_of_charge"], 1e-9),
        "alt_end_m": alt[-1],
    }


def _chain(first: dict, rest: list[dict]) -> tuple[list[float], list[float], list[float]]:
    """Stored energy [Wh] of the chained night: (POSIX hours, energy, sun elevation).
    ValueError if a chained segment touched empty or full."""
    t, e, s = list(first["utc_h"]), list(first["energy_wh"]), list(first["sun_deg"])
    for seg in rest:
        if min(seg["soc"]) <= 1e-6 or max(seg["soc"][1:]) >= 1.0 - 1e-6:
            raise ValueError("a chained segment reached an empty or a full battery: chain invalid")
        offset = e[-1] - seg["energy_wh"][0]
        t += seg["utc_h"][1:]
        e += [x + offset for x in seg["energy_wh"][1:]]
        s += seg["sun_deg"][1:]
    return t, e, s


def _dawn(t: list[float], e: list[float], s: list[float], capacity: float) -> dict:
    """State of charge at the first sunrise at the vehicle after the night, and the minimum."""
    night = False
    out: dict = {}
    for ti, ei, si in zip(t, e, s, strict=True):
        if si < 0.0:
            night = True
        elif night:
            out.update(dawn_utc=_iso(ti), soc_at_dawn=ei / capacity)
            break
    i = min(range(len(e)), key=e.__getitem__)
    out.update(soc_min=e[i] / capacity, soc_min_utc=_iso(t[i]))
    return out


def _iso(posix_h: float) -> str:
    return datetime.fromtimestamp(posix_h * H, UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def _run_all(jobs: list[tuple[str, dict]], workers: int, tmp: Path) -> dict[str, dict]:
    def one(job: tuple[str, dict]) -> tuple[str, dict]:
        key, data = job
        out = tmp / f"{key}.mcap"
        _fly(data, out)
        return key, _read(out, data["start_time"])

    with ThreadPoolExecutor(max_workers=workers) as pool:
        return dict(pool.map(one, jobs))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=["june", "june_schedule", "december", "all"], default="all")
    ap.add_argument("--jobs", type=int, default=6, help="segments flown at the same time")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "haps_night.json"))
    args = ap.parse_args()
    cases = ["june", "june_schedule", "december"] if args.case == "all" else [args.case]
    jobs: list[tuple[str, dict]] = []
    june = "haps_station_june_47n"
    if {"june", "june_schedule"} & set(cases):
        b = JUNE_BOUNDS_H
        for i in range(len(b) - 1):
            soc = 1.0 if i == 0 else MID_SOC
            start = JUNE_NIGHT + timedelta(hours=b[i])
            jobs.append((f"june{i}", _segment_toml(june, start, b[i + 1] - b[i], soc)))
    if "june_schedule" in cases:
        at_ceiling = (21_000.0, 29.4)  # EAS 7.3 m/s, TECS's floor: the shipped 23.8 m/s TAS is below it there
        sched = _segment_toml(f"{june}_altitude_schedule", JUNE_NIGHT, JUNE_BOUNDS_H[1], 1.0, at_ceiling)
        jobs.append(("june_schedule0", sched))
    if "december" in cases:
        dec = "haps_station_december_60n"
        start = tomllib.loads((ROOT / "scenarios" / f"{dec}.toml").read_text())["start_time"]
        b = DECEMBER_BOUNDS_H
        for i in range(len(b) - 1):
            soc = 1.0 if i == 0 else MID_SOC
            jobs.append((f"december{i}", _segment_toml(dec, start + timedelta(hours=b[i]), b[i + 1] - b[i], soc)))
    with tempfile.TemporaryDirectory() as d:
        segs = _run_all(jobs, args.jobs, Path(d))
    results: dict = {}
    if "june" in segs:
        results["june_start_curtailed_w"] = segs["june0"]["curtailed_w"][0]
    for case in cases:
        if case == "december":
            n = len(DECEMBER_BOUNDS_H) - 1
            t, e, _ = _chain(segs["december0"], [segs[f"december{i}"] for i in range(1, n)])
            empty = next((_iso(ti) for ti, ei in zip(t, e, strict=True) if ei <= 0.0), None)
            results[case] = {"energy_depleted_utc": empty, "capacity_wh": segs["december0"]["capacity_wh"]}
            continue
        first = segs["june_schedule0" if case == "june_schedule" else "june0"]
        if case == "june_schedule" and abs(first["alt_end_m"] - 18_000.0) > 50.0:
            raise ValueError(f"june_schedule: first segment ends at {first['alt_end_m']:.0f} m, not the floor")
        n = len(JUNE_BOUNDS_H) - 1
        t, e, s = _chain(first, [segs[f"june{i}"] for i in range(1, n)])
        results[case] = _dawn(t, e, s, first["capacity_wh"]) | {"capacity_wh": first["capacity_wh"]}
    print(json.dumps(results, indent=1))
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
