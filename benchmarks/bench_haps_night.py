"""The HAPS's night energy budget from closed-loop power pieces: state of charge at dawn (June,
with and without the altitude schedule) and the time the battery runs empty (December).

A full 24 h closed-loop run (``bench_haps_24h.py``) takes ~30 min of CPU; this script flies only
the pieces whose power differs, each from the shipped scenario (same aircraft, mission, energy
model, EKF) started at the piece's UTC time from a trim, and integrates the rest:

- ``station``: 18 km at the shipped station speed, at night (21:00 UTC), 20 min: mean propulsion
  electrical power over the last 15 min (after the trim transient);
- ``ceiling``: the altitude-schedule scenario at its 21 km ceiling (17:00 UTC, battery full:
  schedule ``up``), 20 min: mean propulsion power there;
- ``glide``: the same at 21 km with the battery at the schedule's ``soc_low`` (19:00 UTC):
  TECS glides to the 18 km floor; its duration and propulsion energy.

Then per minute from noon (battery full: the shipped June run fills it by 08:33 UTC and solar
power exceeds the consumption until ~18:00) to 06:00 UTC the next day, the project's own models:
array power of a level wing at the site (``sim.energy.solar``, pvlib) and the battery
(``sim.energy.battery``) under the measured propulsion plus the loads. June with the schedule
flies ``ceiling`` power until the battery falls to ``soc_low``, then the ``glide``, then
``station``. December starts at the shipped 06:00 UTC, full, at ``station`` power (same altitude
and speed). What it leaves out: bank in turns on the array (level wing), TECS transients, the
aircraft's drift on the square.

    python benchmarks/bench_haps_night.py [--out benchmarks/results/haps_night.json]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import tomllib
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sim.energy.altitude_schedule import AltitudeManager, AltitudeSchedule  # noqa: E402
from sim.energy.battery import Battery  # noqa: E402
from sim.energy.params import EnergyParams  # noqa: E402
from sim.energy.solar import SunTracker, array_power  # noqa: E402
from sim.mcap_read import read_topic  # noqa: E402

JUNE = "haps_station_june_47n"
SCHEDULE = "haps_station_june_47n_altitude_schedule"
DECEMBER = "haps_station_december_60n"
AT_CEILING = (21_000.0, 29.4)  # [m], TAS [m/s] = EAS 7.3 m/s, TECS's floor there
STEP_S = 60.0


def _scenario(name: str, start: datetime, minutes: float, soc: float, at: tuple[float, float] | None) -> dict:
    """The shipped scenario ``name`` as a dict, from ``start`` for ``minutes`` at ``soc``, at
    ``at`` = (altitude [m], TAS [m/s]) instead of the shipped initial state if given."""
    data = tomllib.loads((ROOT / "scenarios" / f"{name}.toml").read_text())
    data["start_time"], data["duration"] = start, minutes * 60.0
    vehicle = data["vehicle"][0]
    vehicle.setdefault("energy", {})["initial_soc"] = soc
    if at is not None:
        vehicle["initial"]["altitude"], vehicle["initial"]["airspeed"] = at
    return data


def _fly(data: dict, out: Path) -> dict[str, np.ndarray]:
    """Fly ``data`` in a child interpreter; the logged energy record and altitude per second."""
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
        raise RuntimeError(f"{out.name} failed: {proc.stderr.strip().splitlines()[-1:]}")
    rec = [m for _, m in read_topic(out, "/haps/energy")]
    alt = [m["alt_msl_m"] for _, m in read_topic(out, "/haps/truth/state")]
    n = min(len(rec), len(alt))
    return {
        "t": np.array([r["t"] for r in rec[:n]]),
        "propulsion_w": np.array([r["propulsion_w"] for r in rec[:n]]),
        "alt_m": np.array(alt[:n]),
    }


def _pieces(tmp: Path, soc_low: float) -> dict[str, float]:
    """Fly the three pieces at once; their powers [W] and the glide's duration [s]."""
    day = datetime(2026, 6, 21, tzinfo=UTC)
    jobs = {
        "station": _scenario(JUNE, day + timedelta(hours=21), 20.0, 0.7, None),
        "ceiling": _scenario(SCHEDULE, day + timedelta(hours=17), 20.0, 1.0, AT_CEILING),
        "glide": _scenario(SCHEDULE, day + timedelta(hours=19), 80.0, soc_low, AT_CEILING),
    }
    with ThreadPoolExecutor(max_workers=len(jobs)) as pool:
        logs = dict(zip(jobs, pool.map(lambda k: _fly(jobs[k], tmp / f"{k}.mcap"), jobs), strict=True))
    out = {k: float(logs[k]["propulsion_w"][logs[k]["t"] > 300.0].mean()) for k in ("station", "ceiling")}
    g = logs["glide"]
    down = g["alt_m"] < 18_010.0
    if not down.any():
        raise ValueError("glide: the aircraft did not reach the 18 km floor within 80 min")
    i = int(np.argmax(down))
    out["glide_s"] = float(g["t"][i])
    out["glide_w"] = float(g["propulsion_w"][: i + 1].mean())
    return out


def _integrate(name: str, start: datetime, hours: float, soc: float, power_w: Callable[[float, float], float]) -> dict:
    """Minute steps of the level-wing array and the battery from ``start``; ``power_w(t, soc)``
    is the propulsion power [W]. SoC at the first sunrise after a night, minimum, depletion."""
    params = EnergyParams.load(ROOT / "aircraft" / "haps" / "energy.toml")
    site = tomllib.loads((ROOT / "scenarios" / f"{name}.toml").read_text())["origin"]
    sun, battery = SunTracker(start, params.atmosphere), Battery(params.battery, soc)
    loads = params.loads.avionics_w + params.loads.payload_w
    out: dict = {}
    night, low = False, (soc, start)
    for t in np.arange(0.0, hours * 3600.0, STEP_S):
        s = sun.sample(float(t), site["lat"], site["lon"], 18_000.0)
        solar, _ = array_power(params.array, s, np.zeros(3))
        battery.step(solar - power_w(float(t), battery.soc) - loads, STEP_S)
        now = start + timedelta(seconds=float(t) + STEP_S)
        if battery.soc < low[0]:
            low = (battery.soc, now)
        if s.elevation_deg < 0.0:
            night = True
        elif night and "soc_at_dawn" not in out:
            out.update(dawn_utc=f"{now:%Y-%m-%dT%H:%M}Z", soc_at_dawn=battery.soc)
        if battery.energy_wh <= 0.0 and "energy_depleted_utc" not in out:
            out["energy_depleted_utc"] = f"{now:%Y-%m-%dT%H:%M}Z"
    out.update(soc_min=low[0], soc_min_utc=f"{low[1]:%Y-%m-%dT%H:%M}Z", capacity_wh=params.battery.capacity_wh)
    return out


def _schedule_power(p: dict[str, float], schedule: AltitudeSchedule) -> Callable[[float, float], float]:
    """Propulsion power [W] of the schedule night: ceiling while ``up``, then the glide, then
    station. Starts ``up`` (battery full)."""
    manager = AltitudeManager(schedule, 1.0)
    glide_from: list[float] = []  # the time the schedule turned down [s]

    def power(t: float, soc: float) -> float:
        if not glide_from:
            if manager.altitude(soc) > schedule.floor_m:
                return p["ceiling"]
            glide_from.append(t)
        return p["glide_w"] if t - glide_from[0] < p["glide_s"] else p["station"]

    return power


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "haps_night.json"))
    args = ap.parse_args()
    opts = tomllib.loads((ROOT / "scenarios" / f"{SCHEDULE}.toml").read_text())["vehicle"][0]["energy"]
    sched_opts = opts["altitude_schedule"]
    schedule = AltitudeSchedule(18_000.0, 21_000.0, sched_opts["soc_high"], sched_opts["soc_low"])
    with tempfile.TemporaryDirectory() as d:
        p = _pieces(Path(d), schedule.soc_low)
    noon = datetime(2026, 6, 21, 12, tzinfo=UTC)
    dec = tomllib.loads((ROOT / "scenarios" / f"{DECEMBER}.toml").read_text())["start_time"]
    results = {
        "pieces": p,
        "june": _integrate(JUNE, noon, 18.0, 1.0, lambda t, soc: p["station"]),
        "june_schedule": _integrate(SCHEDULE, noon, 18.0, 1.0, _schedule_power(p, schedule)),
        "december": _integrate(DECEMBER, dec, 24.0, 1.0, lambda t, soc: p["station"]),
    }
    print(json.dumps(results, indent=1))
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
