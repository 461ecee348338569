"""Closed-loop speed with logging, against the bare JSBSim step rate measured in the same run.

Cases (``--case``), each flown with ideal sensors (``perfect``) and with the sensor models +
INS/GNSS EKF the scenarios use by default (``ekf``):
- ``haps``: the HAPS box mission (planner, L1, TECS at 10 Hz, MCAP at 10 Hz) vs bare ``run()``
  of the trimmed HAPS model. Target: >= 200x real time.
- ``multirotor``: the quadrotor square mission (take-off, carrot follower, cascaded controller
  at 60 Hz over the JSBSim inner loops, MCAP at 10 Hz) vs bare ``run()`` of JSBSim's shipped
  F450 at the same 240 Hz. Target: >= 50x real time.
Both numbers come from this machine in this run, so the ratio carries across machines.

    python benchmarks/bench_closed_loop.py [--case haps|multirotor|all] [--repeat 3]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from aircraft.registry import get_airframe  # noqa: E402
from sim.geodesy import GeoPoint  # noqa: E402
from sim.jsbsim_plant import InitialConditions, JSBSimPlant  # noqa: E402
from sim.runner import run_scenario  # noqa: E402
from sim.scenario import parse_scenario  # noqa: E402

CASES = {
    # case: (scenario, sim seconds, bare model, its folder's airframe or None (shipped), rate, target)
    "haps": ("haps_box_mission", 600.0, "haps", "haps", 120, 200),
    "multirotor": ("quad_square_mission", 60.0, "F450", None, 240, 50),
}


def bare_steps_per_s(model: str, airframe: str | None, rate: int, steps: int) -> float:
    folder = get_airframe(airframe).folder if airframe else None
    plant = JSBSimPlant(model, 1.0 / rate, GeoPoint(47.0, 8.0), folder)
    alt = 18000.0 if model == "haps" else 100.0
    plant.initialise(InitialConditions(GeoPoint(47.0, 8.0, alt), tas_mps=26.0 if model == "haps" else 0.0))
    if model == "haps":
        plant.trim()
    run = plant.fdm.run
    t0 = time.perf_counter()
    for _ in range(steps):
        run()
    return steps / (time.perf_counter() - t0)


def closed_loop_rtf(scenario_name: str, sim_seconds: float, estimator: str) -> float:
    data = tomllib.loads((ROOT / "scenarios" / f"{scenario_name}.toml").read_text())
    for v in data["vehicle"]:
        v["estimator"] = estimator
    scenario = parse_scenario(data, scenario_name)
    with tempfile.TemporaryDirectory() as d:
        r = run_scenario(scenario, Path(d) / "bench.mcap", duration=sim_seconds)
    return r.sim_time_s / r.wall_time_s


def measure(case: str, repeat: int) -> dict:
    scenario, sim_s, model, airframe, rate, target = CASES[case]
    bare = max(bare_steps_per_s(model, airframe, rate, int(sim_s * rate)) for _ in range(repeat))
    out = {
        "case": case,
        "scenario": scenario,
        "bare_model": model,
        "bare_steps_per_s": round(bare),
        "bare_real_time_factor": round(bare / rate, 1),
        "target_real_time_factor": target,
        "sim_seconds": sim_s,
    }
    for estimator in ("perfect", "ekf"):
        rtf = max(closed_loop_rtf(scenario, sim_s, estimator) for _ in range(repeat))
        out[f"{estimator}_real_time_factor"] = round(rtf, 1)
        out[f"{estimator}_ratio_to_bare"] = round(rtf * rate / bare, 3)
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--case", choices=[*CASES, "all"], default="all")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    out = ROOT / "benchmarks" / "results"
    out.mkdir(exist_ok=True)
    for case in CASES if args.case == "all" else [args.case]:
        res = measure(case, args.repeat)
        (out / f"closed_loop_{case}.json").write_text(json.dumps(res, indent=2))
        print(f"[{case}]")
        for k, v in res.items():
            print(f"  {k:30s} {v}")


if __name__ == "__main__":
    main()
