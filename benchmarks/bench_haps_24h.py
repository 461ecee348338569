"""24 h HAPS flights with the energy model: wall time, peak memory and the energy outcome.

Peak memory is the flying interpreter's peak resident set size (``ru_maxrss`` of the child,
which includes the log writer it waits for), against the target ``PEAK_RSS_TARGET_MIB``.

Cases (``--case``), each the shipped scenario flown whole in a fresh interpreter (so its peak
resident memory is its own):
- ``june``: ``scenarios/haps_station_june_47n.toml`` — state of charge at dawn (first sunrise
  at the vehicle after the night) and its minimum.
- ``december``: ``scenarios/haps_station_december_60n.toml`` — time of ``energy_depleted``.
- ``june_schedule``: the June flight with the altitude schedule (climb to 21 km on a full
  battery, glide to the 18 km floor): state of charge at dawn against ``june``.
Speed is reported as the real-time factor and against bare ``run()`` steps of the trimmed HAPS
model measured in the same run (so the ratio carries across machines).

    python benchmarks/bench_haps_24h.py [--case june|december|june_schedule|all] [--hours 24]
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_closed_loop import bare_steps_per_s  # noqa: E402

from sim.mcap_read import read_topic  # noqa: E402

PEAK_RSS_TARGET_MIB = 300.0  # issue 19: a 24 h HAPS flight under 300 MB

CASES = {
    "june": "haps_station_june_47n",
    "december": "haps_station_december_60n",
    "june_schedule": "haps_station_june_47n_altitude_schedule",
}


def fly(scenario: str, hours: float, out: Path) -> dict:
    """Run the scenario in a child interpreter; wall time [s] and its peak RSS [MiB]."""
    toml = str(ROOT / "scenarios" / f"{scenario}.toml")
    code = (
        f"import sys; sys.path.insert(0, {str(ROOT)!r})\n"
        "from sim.runner import run_scenario\n"
        "from sim.scenario import load_scenario\n"
        f"s, text = load_scenario({toml!r})\n"
        f"r = run_scenario(s, {str(out)!r}, scenario_text=text, duration={hours * 3600.0!r})\n"
        "print(r.status, r.sim_time_s, r.wall_time_s)\n"
    )
    t0 = time.perf_counter()
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"{scenario}: run failed: {proc.stderr.strip().splitlines()[-1:]}")
    wall = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    status, sim_s, run_wall = proc.stdout.split()[-3:]
    return {
        "status": status,
        "sim_time_s": float(sim_s),
        "wall_s": wall,
        "run_wall_s": float(run_wall),
        "peak_rss_mib": max(peak, before) / 1024.0,
    }


def energy_outcome(path: Path) -> dict:
    """State of charge at the first sunrise after a night, its minimum, and depletion."""
    rec = [m for _, m in read_topic(path, "/haps/energy")]
    events = [(t, m.message) for t, m in read_topic(path, "/log")]
    out: dict = {"soc_start": rec[0]["state_of_charge"], "soc_end": rec[-1]["state_of_charge"]}
    low = min(rec, key=lambda r: r["state_of_charge"])
    out["soc_min"], out["soc_min_t_s"] = low["state_of_charge"], low["t"]
    night = False
    for r in rec:
        if r["sun_elevation_deg"] < 0.0:
            night = True
        elif night:
            out["dawn_t_s"], out["soc_at_dawn"] = r["t"], r["state_of_charge"]
            break
    depleted = [t for t, msg in events if "energy_depleted" in msg]
    out["energy_depleted_t_s"] = depleted[0] if depleted else None
    out["solar_wh"] = rec[-1]["cumulative_wh"]["solar"]
    out["propulsion_wh"] = rec[-1]["cumulative_wh"]["propulsion"]
    out["capacity_wh"] = rec[0]["energy_wh"] / max(rec[0]["state_of_charge"], 1e-9)
    alt = [m["alt_msl_m"] for _, m in read_topic(path, "/haps/truth/state")]
    out["alt_min_m"], out["alt_max_m"] = min(alt), max(alt)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=[*CASES, "all"], default="all")
    ap.add_argument("--hours", type=float, default=24.0)
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "haps_24h.json"))
    args = ap.parse_args()
    bare = bare_steps_per_s("haps", "haps", 120, 200_000)  # the HAPS trimmed at 18 km, 120 Hz
    results: dict = {"bare_jsbsim_steps_per_s": bare, "cases": {}}
    for case in CASES if args.case == "all" else [args.case]:
        with tempfile.TemporaryDirectory() as d:
            log = Path(d) / f"{case}.mcap"
            r = fly(CASES[case], args.hours, log)
            r["real_time_factor"] = r["sim_time_s"] / r["run_wall_s"]
            r["vs_bare_jsbsim"] = r["real_time_factor"] * 120.0 / bare
            r["log_mib"] = log.stat().st_size / 2**20
            r["energy"] = energy_outcome(log)
        r["peak_rss_within_target"] = r["peak_rss_mib"] < PEAK_RSS_TARGET_MIB
        results["cases"][case] = r
        print(case, json.dumps(r, indent=1, default=float), flush=True)
        print(f"{case}: peak RSS {r['peak_rss_mib']:.0f} MiB (target < {PEAK_RSS_TARGET_MIB:.0f})", flush=True)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(results, indent=1, default=float))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
