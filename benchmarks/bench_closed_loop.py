"""Closed-loop speed with logging, against the bare JSBSim step rate measured in the same run.

Cases (``--case``), each flown in the variants (``VARIANTS``) it lists:
- ``perfect``: ideal sensors, the inner loops on JSBSim's truth;
- ``ekf_truth_inner``: the sensor models + INS/GNSS EKF, the inner loops on the truth, the IMU at
  its rate before the inner loops closed on the estimate (HAPS 60 Hz, quadrotor 120 Hz): the
  default of the code before issue #15 item 4;
- ``ekf``: the default, the inner loops on the EKF attitude propagated with the bias-corrected
  gyro and on the gyro rates, the IMU at the plant rate;
- ``ekf_wind_profile``: ``ekf`` in ``[wind] standard = "midlatitude_jet"`` (the wind at the
  vehicle's altitude set at the control rate).

- ``haps``: the HAPS box mission (planner, L1, TECS at 10 Hz, MCAP at 10 Hz) vs bare ``run()``
  of the trimmed HAPS model. Target: >= 200x real time.
- ``multirotor``: the quadrotor square mission (take-off, carrot follower, cascaded controller
  at 60 Hz over the JSBSim inner loops, MCAP at 10 Hz) vs bare ``run()`` of JSBSim's shipped
  F450 at the same 240 Hz. Target: >= 50x real time.
- ``mixed_reachset`` (EKF only): ``scenarios/mixed_haps_quad_reachset.toml``, the HAPS box at
  18 km and a quadrotor on the reach-set planner meeting two intruders, vs bare ``run()`` of the
  same models, this project's HAPS (120 Hz) and quadrotor (240 Hz, its FCS included), for the
  same sim time. Target: >= 50x real time.
- ``fleet8_reachset`` (EKF only): ``scenarios/reachset_fleet8.toml``, eight quadrotors on the
  reach-set planner (four head-on pairs 500 m apart), vs bare ``run()`` of eight of this
  project's quadrotors. Target: >= 8x real time.
Both numbers come from this machine in this run, so the ratio carries across machines. Each is
reported on the wall clock (``*_real_time_factor``, what the targets are about) and on this
process's CPU time (``*_cpu_*``: steadier on a loaded machine; it leaves out the MCAP writer,
which runs in its own process).
``--paths baseline,current`` flies the reach-set cases as before issue #16 as well, in the same
run: the previous intruder rating (``bench_reachset.LatticeIntruderModel``) and no broad phase
(every vehicle senses every other body). ``--before TREE`` also flies the ``ekf`` variant with
another code tree (e.g. ``git archive <commit> | tar -x -C TREE``), in a child process importing
that tree's ``sim``, alternating with this tree's runs (``before_ekf_*``).

    python benchmarks/bench_closed_loop.py [--case haps|multirotor|mixed_reachset|fleet8_reachset|all]
        [--repeat 3] [--paths current|baseline,current] [--sim-seconds S] [--before TREE]
"""

from __future__ import annotations

import argparse
import json
import subprocess
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
from sim.vehicle import Vehicle  # noqa: E402

# bare model, its folder's airframe (None: shipped), rate
HAPS, F450, QUAD = ("haps", "haps", 120), ("F450", None, 240), ("quadrotor", "quadrotor", 240)
BARE_ALT_M = {"haps": 18000.0, "quadrotor": 10000.0}  # start altitude of the bare plant (else 100 m)
VARIANTS = ("perfect", "ekf_truth_inner", "ekf", "ekf_wind_profile")
IMU_HZ_BEFORE = {"haps": 60.0, "quadrotor": 120.0}  # the IMU defaults while the inner loops flew on truth
CASES = {
    # case: (scenario, sim seconds, bare plants (model, airframe, rate, count), target, variants)
    "haps": ("haps_box_mission", 300.0, [(*HAPS, 1)], 200, VARIANTS),
    "multirotor": ("quad_square_mission", 60.0, [(*F450, 1)], 50, VARIANTS),
    "mixed_reachset": ("mixed_haps_quad_reachset", 120.0, [(*HAPS, 1), (*QUAD, 1)], 50, ("ekf",)),
    "fleet8_reachset": ("reachset_fleet8", 60.0, [(*QUAD, 8)], 8, ("ekf",)),
}


def bare_rates(model: str, airframe: str | None, rate: int, steps: int) -> tuple[float, float]:
    """Bare ``run()`` steps per second of wall time and of CPU time (the quadrotor falls from
    10 km with its motors idle: airborne throughout, as in the closed loop)."""
    folder = get_airframe(airframe).folder if airframe else None
    plant = JSBSimPlant(model, 1.0 / rate, GeoPoint(47.0, 8.0), folder)
    alt = BARE_ALT_M.get(model, 100.0)
    plant.initialise(InitialConditions(GeoPoint(47.0, 8.0, alt), tas_mps=26.0 if model == "haps" else 0.0))
    if model == "haps":
        plant.trim()
    run = plant.fdm.run
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(steps):
        run()
    return steps / (time.perf_counter() - t0), steps / (time.process_time() - c0)


def bare_steps_per_s(model: str, airframe: str | None, rate: int, steps: int) -> float:
    """Bare ``run()`` steps per second of wall time (:func:`bare_rates`)."""
    return bare_rates(model, airframe, rate, steps)[0]


def closed_loop_rtf(scenario_name: str, sim_seconds: float, variant: str) -> tuple[float, float]:
    """Real-time factors, on the wall clock and on this process's CPU time, of the shipped
    scenario flown in ``variant`` (see the module doc)."""
    data = tomllib.loads((ROOT / "scenarios" / f"{scenario_name}.toml").read_text())
    for v in data["vehicle"]:
        v["estimator"] = "perfect" if variant == "perfect" else "ekf"
        if variant == "ekf_truth_inner":
            v.setdefault("sensors", {}).setdefault("imu", {})["rate_hz"] = IMU_HZ_BEFORE[v["aircraft"]]
    if variant == "ekf_wind_profile":
        data["wind"] = {"standard": "midlatitude_jet"}
    scenario = parse_scenario(data, scenario_name)
    saved = Vehicle.inner_loops_on_estimate
    Vehicle.inner_loops_on_estimate = variant != "ekf_truth_inner"
    try:
        with tempfile.TemporaryDirectory() as d:
            c0 = time.process_time()
            r = run_scenario(scenario, Path(d) / "bench.mcap", duration=sim_seconds)
            cpu = time.process_time() - c0
    finally:
        Vehicle.inner_loops_on_estimate = saved
    return r.sim_time_s / r.wall_time_s, r.sim_time_s / cpu


FLY_EKF = """
import sys, time, tomllib, tempfile
from pathlib import Path
sys.path.insert(0, ".")
from sim.runner import run_scenario
from sim.scenario import parse_scenario
name, seconds = sys.argv[1], float(sys.argv[2])
data = tomllib.loads(Path("scenarios", name + ".toml").read_text())
for v in data["vehicle"]:
    v["estimator"] = "ekf"
with tempfile.TemporaryDirectory() as d:
    c0 = time.process_time()
    r = run_scenario(parse_scenario(data, name), Path(d) / "bench.mcap", duration=seconds)
    cpu = time.process_time() - c0
print(r.sim_time_s / r.wall_time_s, r.sim_time_s / cpu)
"""


def tree_rtf(tree: Path, scenario_name: str, sim_seconds: float) -> tuple[float, float]:
    """:func:`closed_loop_rtf` of the ``ekf`` variant flown by the code tree ``tree``."""
    cmd = [sys.executable, "-c", FLY_EKF, scenario_name, str(sim_seconds)]
    out = subprocess.run(cmd, cwd=tree.resolve(), capture_output=True, text=True, check=True).stdout.split()
    return float(out[-2]), float(out[-1])


def _factors(out: dict, tag: str, runs: list[tuple[float, float]], bare_rtf: float, bare_cpu_rtf: float) -> None:
    rtf, cpu_rtf = max(w for w, _ in runs), max(c for _, c in runs)
    out[f"{tag}_real_time_factor"] = round(rtf, 2)
    out[f"{tag}_ratio_to_bare"] = round(rtf / bare_rtf, 3)
    out[f"{tag}_cpu_real_time_factor"] = round(cpu_rtf, 2)
    out[f"{tag}_cpu_ratio_to_bare"] = round(cpu_rtf / bare_cpu_rtf, 3)


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


def measure(
    case: str, repeat: int, paths: list[str], sim_seconds: float | None = None, before: Path | None = None
) -> dict:
    """Real-time factors of the closed loop and of bare stepping of the same plants: the bare
    wall time of one sim second is the sum over the plants of count x rate / steps per second.
    ``sim_seconds`` overrides the case's flight time; ``before``: a code tree to fly the ``ekf``
    variant with as well, alternating with this tree's runs."""
    scenario, sim_s, plants, target, variants = CASES[case]
    sim_s = sim_seconds or sim_s
    rates = {m: [bare_rates(m, a, r, int(sim_s * r)) for _ in range(repeat)] for m, a, r, _ in plants}
    steps = {m: max(w for w, _ in v) for m, v in rates.items()}
    cpu_steps = {m: max(c for _, c in v) for m, v in rates.items()}
    bare_rtf = 1.0 / sum(n * r / steps[m] for m, _, r, n in plants)
    bare_cpu_rtf = 1.0 / sum(n * r / cpu_steps[m] for m, _, r, n in plants)
    out = {
        "case": case,
        "scenario": scenario,
        "bare_plants": {m: n for m, _, _, n in plants},
        "bare_steps_per_s": {m: round(v) for m, v in steps.items()},
        "bare_real_time_factor": round(bare_rtf, 1),
        "bare_cpu_real_time_factor": round(bare_cpu_rtf, 1),
        "target_real_time_factor": target,
        "sim_seconds": sim_s,
    }
    reachset = "reachset" in case
    for path in paths if reachset else ["current"]:
        tag = "" if path == "current" else f"{path}_"
        with code_path(path), broad_phase(path):
            for variant in variants:
                runs, before_runs = [], []
                for _ in range(repeat):
                    runs.append(closed_loop_rtf(scenario, sim_s, variant))
                    if before is not None and variant == "ekf" and path == "current":
                        before_runs.append(tree_rtf(before, scenario, sim_s))
                _factors(out, f"{tag}{variant}", runs, bare_rtf, bare_cpu_rtf)
                if before_runs:
                    _factors(out, "before_ekf", before_runs, bare_rtf, bare_cpu_rtf)
    out["meets_target"] = out["ekf_real_time_factor"] >= target
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--case", choices=[*CASES, "all"], default="all")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--sim-seconds", type=float, default=None, help="override the cases' flight time [s]")
    ap.add_argument("--paths", default="current", help="comma-separated: baseline (before issue #16), current")
    ap.add_argument("--before", type=Path, default=None, help="a code tree to fly the ekf variant with as well")
    args = ap.parse_args()
    out = ROOT / "benchmarks" / "results"
    out.mkdir(exist_ok=True)
    for case in CASES if args.case == "all" else [args.case]:
        res = measure(case, args.repeat, args.paths.split(","), args.sim_seconds, args.before)
        (out / f"closed_loop_{case}.json").write_text(json.dumps(res, indent=2))
        print(f"[{case}]")
        for k, v in res.items():
            print(f"  {k:30s} {v}")


if __name__ == "__main__":
    main()
