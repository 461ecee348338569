"""Closed-loop speed with logging, against the bare JSBSim step rate measured in the same run.

Cases (``--case``), each flown with ideal sensors (``perfect``) and with the sensor models +
INS/GNSS EKF the scenarios use by default (``ekf``):
- ``haps``: the HAPS box mission (planner, L1, TECS at 10 Hz, MCAP at 10 Hz) vs bare ``run()``
  of the trimmed HAPS model. Target: >= 200x real time.
- ``multirotor``: the quadrotor square mission (take-off, carrot follower, cascaded controller
  at 60 Hz over the JSBSim inner loops, MCAP at 10 Hz) vs bare ``run()`` of JSBSim's shipped
  F450 at the same 240 Hz. Target: >= 50x real time.
- ``mixed_reachset`` (EKF only): ``scenarios/mixed_haps_quad_reachset.toml``, the HAPS box at
  18 km and a quadrotor on the reach-set planner meeting two intruders, vs bare ``run()`` of the
  HAPS (120 Hz) and the F450 (240 Hz) for the same sim time. Target: >= 50x real time.
- ``fleet8_reachset`` (EKF only): ``scenarios/reachset_fleet8.toml``, eight quadrotors on the
  reach-set planner (four head-on pairs 500 m apart), vs bare ``run()`` of eight F450s. Target:
  >= 8x real time.
Both numbers come from this machine in this run, so the ratio carries across machines.
``--paths baseline,current`` flies the reach-set cases as before issue #16 as well, in the same
run: the previous intruder rating (``bench_reachset.LatticeIntruderModel``) and no broad phase
(every vehicle senses every other body).

    python benchmarks/bench_closed_loop.py [--case haps|multirotor|mixed_reachset|fleet8_reachset|all]
        [--repeat 3] [--paths current|baseline,current] [--sim-seconds S]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
import tomllib
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import numpy as np  # noqa: E402
from bench_reachset import code_path  # noqa: E402

import sim.world as world  # noqa: E402
from aircraft.registry import get_airframe  # noqa: E402
from sim.geodesy import GeoPoint  # noqa: E402
from sim.jsbsim_plant import InitialConditions, JSBSimPlant  # noqa: E402
from sim.runner import run_scenario  # noqa: E402
from sim.scenario import parse_scenario  # noqa: E402

HAPS, F450 = ("haps", "haps", 120), ("F450", None, 240)  # bare model, its folder's airframe (None: shipped), rate
CASES = {
    # case: (scenario, sim seconds, bare plants (model, airframe, rate, count), target, estimators)
    "haps": ("haps_box_mission", 600.0, [(*HAPS, 1)], 200, ("perfect", "ekf")),
    "multirotor": ("quad_square_mission", 60.0, [(*F450, 1)], 50, ("perfect", "ekf")),
    "mixed_reachset": ("mixed_haps_quad_reachset", 120.0, [(*HAPS, 1), (*F450, 1)], 50, ("ekf",)),
    "fleet8_reachset": ("reachset_fleet8", 60.0, [(*F450, 8)], 8, ("ekf",)),
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


@contextmanager
def broad_phase(path: str) -> Iterator[None]:
    """``baseline``: ``World.sense`` without the broad phase (every other body to every vehicle)."""
    if path == "current":
        yield
        return
    saved = world.relevant
    world.relevant = lambda pos, speed, radius, awareness, *a: [
        np.flatnonzero(np.arange(len(pos)) != i) for i in range(len(awareness))
    ]
    try:
        yield
    finally:
        world.relevant = saved


def measure(case: str, repeat: int, paths: list[str], sim_seconds: float | None = None) -> dict:
    """Real-time factors of the closed loop and of bare stepping of the same plants: the bare
    wall time of one sim second is the sum over the plants of count x rate / steps per second.
    ``sim_seconds`` overrides the case's flight time."""
    scenario, sim_s, plants, target, estimators = CASES[case]
    sim_s = sim_seconds or sim_s
    steps = {m: max(bare_steps_per_s(m, a, r, int(sim_s * r)) for _ in range(repeat)) for m, a, r, _ in plants}
    bare_rtf = 1.0 / sum(n * r / steps[m] for m, _, r, n in plants)
    out = {
        "case": case,
        "scenario": scenario,
        "bare_plants": {m: n for m, _, _, n in plants},
        "bare_steps_per_s": {m: round(v) for m, v in steps.items()},
        "bare_real_time_factor": round(bare_rtf, 1),
        "target_real_time_factor": target,
        "sim_seconds": sim_s,
    }
    reachset = "reachset" in case
    for path in paths if reachset else ["current"]:
        tag = "" if path == "current" else f"{path}_"
        with code_path(path), broad_phase(path):
            for estimator in estimators:
                rtf = max(closed_loop_rtf(scenario, sim_s, estimator) for _ in range(repeat))
                out[f"{tag}{estimator}_real_time_factor"] = round(rtf, 2)
                out[f"{tag}{estimator}_ratio_to_bare"] = round(rtf / bare_rtf, 3)
    out["meets_target"] = out[f"{estimators[-1]}_real_time_factor"] >= target
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--case", choices=[*CASES, "all"], default="all")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--sim-seconds", type=float, default=None, help="override the cases' flight time [s]")
    ap.add_argument("--paths", default="current", help="comma-separated: baseline (before issue #16), current")
    args = ap.parse_args()
    out = ROOT / "benchmarks" / "results"
    out.mkdir(exist_ok=True)
    for case in CASES if args.case == "all" else [args.case]:
        res = measure(case, args.repeat, args.paths.split(","), args.sim_seconds)
        (out / f"closed_loop_{case}.json").write_text(json.dumps(res, indent=2))
        print(f"[{case}]")
        for k, v in res.items():
            print(f"  {k:30s} {v}")


if __name__ == "__main__":
    main()
