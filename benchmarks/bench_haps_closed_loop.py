"""HAPS closed-loop speed with logging, against the bare JSBSim step rate of the same model.

Both are measured in this run on this machine, so the ratio is meaningful across machines:
- bare: ``fdm.run()`` of the trimmed HAPS model, no Python work between steps [steps/s];
- closed loop: the box-mission scenario through the runner (planner, guidance, TECS/L1,
  MCAP logging at 10 Hz) [sim s / wall s], and its JSBSim steps per wall second.
Target (issue 2): closed loop >= 200x real time.

    python benchmarks/bench_haps_closed_loop.py [--sim-seconds 600]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from aircraft.registry import get_airframe  # noqa: E402
from sim.frames import GeoPoint  # noqa: E402
from sim.jsbsim_plant import InitialConditions, JSBSimPlant  # noqa: E402
from sim.runner import run_scenario  # noqa: E402
from sim.scenario import load_scenario  # noqa: E402


def bare_step_rate(steps: int) -> float:
    af = get_airframe("haps")
    plant = JSBSimPlant(af.jsbsim_model, 1.0 / af.plant_hz, GeoPoint(47.0, 8.0), af.folder)
    plant.initialise(InitialConditions(GeoPoint(47.0, 8.0, 18000.0), tas_mps=26.0))
    plant.trim()
    run = plant.fdm.run
    t0 = time.perf_counter()
    for _ in range(steps):
        run()
    return steps / (time.perf_counter() - t0)


def closed_loop(sim_seconds: float) -> tuple[float, float]:
    scenario, text = load_scenario(ROOT / "scenarios" / "haps_box_mission.toml")
    with tempfile.TemporaryDirectory() as d:
        r = run_scenario(scenario, Path(d) / "bench.mcap", scenario_text=text, duration=sim_seconds)
        size = (Path(d) / "bench.mcap").stat().st_size
    return r.real_time_factor, size


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sim-seconds", type=float, default=600.0)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    plant_hz = get_airframe("haps").plant_hz
    bare = max(bare_step_rate(int(args.sim_seconds * plant_hz)) for _ in range(args.repeat))
    rtf, size = max(closed_loop(args.sim_seconds) for _ in range(args.repeat))
    closed_steps = rtf * plant_hz
    res = {
        "bare_steps_per_s": round(bare), "bare_real_time_factor": round(bare / plant_hz, 1),
        "closed_loop_real_time_factor": round(rtf, 1), "closed_loop_steps_per_s": round(closed_steps),
        "ratio_closed_to_bare": round(closed_steps / bare, 3), "target_real_time_factor": 200,
        "log_bytes_per_sim_s": round(size / args.sim_seconds), "sim_seconds": args.sim_seconds,
    }
    out = ROOT / "benchmarks" / "results"
    out.mkdir(exist_ok=True)
    (out / "haps_closed_loop.json").write_text(json.dumps(res, indent=2))
    for k, v in res.items():
        print(f"{k:32s} {v}")


if __name__ == "__main__":
    main()
