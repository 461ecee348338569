"""The crash figures of docs/environment.md: the shipped motor failure over many seeds and the
touchdown sink rate of a normal landing.

    PYTHONPATH=. python scripts/crash_numbers.py [--seeds 20]

Motor failure: ``scenarios/quad_motor_failure.toml`` (hover at 30 m AGL, engine 0 stops at 2 s)
flown per seed on the default EKF; prints the crash time and impact speed (``/world/crash``).
Landing: the same quadrotor without the fault, 5 m up, ``land = true``; prints the largest sink
rate [m/s] in the truth log (60 Hz) at the last sample before its gear reaches the ground.
"""

from __future__ import annotations

import argparse
import copy
import tempfile
import tomllib
from pathlib import Path

import numpy as np

from aircraft.registry import get_airframe
from sim.hull import load_hull
from sim.replay.runlog import RunLog
from sim.runner import run_scenario
from sim.scenario import parse_scenario

ROOT = Path(__file__).resolve().parents[1]


def fly(data: dict, out: Path) -> RunLog:
    path = out / "run.mcap"
    run_scenario(parse_scenario(data, "crash_numbers"), path)
    return RunLog(path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=20)
    args = ap.parse_args()
    base = tomllib.loads((ROOT / "scenarios" / "quad_motor_failure.toml").read_text())
    quad = get_airframe("quadrotor")
    gear_depth = load_hull(quad.jsbsim_file).points[0][2]
    crash_t, impact, sink = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        for seed in range(args.seeds):
            (c,) = fly(copy.deepcopy(base) | {"seed": seed}, out).topic("/world/crash").messages
            crash_t.append(c["t"])
            impact.append(c["impact_speed_mps"])
            land = copy.deepcopy(base) | {"seed": seed, "stop_when_complete": True, "logging": {"rate_hz": 60}}
            del land["fault"]
            land["vehicle"][0]["initial"]["altitude"] = 405.0
            land["vehicle"][0]["mission"] |= {"land": True, "waypoints": [{"north": 0, "east": 0, "altitude": 405}]}
            truth = fly(land, out).topic("/quad/truth/state")
            k = int(np.argmax(truth["pos_ned"][:, 2] > -gear_depth))
            sink.append(float(truth["vel_ned"][max(k - 1, 0), 2]))
    for name, v in (("crash time [s]", crash_t), ("impact speed [m/s]", impact), ("landing sink [m/s]", sink)):
        print(f"{name}: min {min(v):.2f}  median {float(np.median(v)):.2f}  max {max(v):.2f}  ({len(v)} seeds)")
    print(f"quadrotor crash_sink_mps: {quad.crash_sink_mps:g}")


if __name__ == "__main__":
    main()
