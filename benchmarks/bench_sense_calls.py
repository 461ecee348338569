"""CPU time per call of the sensing/EKF path's parts, this tree against another one, same run.

Flies ``scenarios/mixed_haps_quad_reachset.toml`` (as shipped) for 5 s, then times the
quadrotor's estimator parts on that state, each call repeated (best of 5 repeats of N calls, this
process's CPU time): the EKF predict over one 60 Hz fusion interval, the stacked update of a
magnetometer and a baro sample (from the same covariance and state each time), the estimate
output, one IMU sample, one gyro-attitude step, one JSBSim step of the quadrotor (the yardstick:
the same in both trees). Warm calls: in the closed loop every part costs more (its code and data
are out of the caches between calls), so read the ratios, not the microseconds. ``--before
TREE`` runs the same in that code tree in a child process (importing its ``sim``) and prints the
ratios before / now.

    python benchmarks/bench_sense_calls.py [--before TREE]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

TIME = r"""
import json, sys, tempfile, time, timeit, tomllib
from pathlib import Path
sys.path.insert(0, ".")
import numpy as np
from sim.mcap_log import McapLog
from sim.scenario import parse_scenario
from sim.scheduler import LockstepScheduler
from sim.sensors.measurements import BaroSample, MagSample
from sim.world import World

name = "mixed_haps_quad_reachset"
sc = parse_scenario(tomllib.loads(Path("scenarios", name + ".toml").read_text()), name)
out = {}
with tempfile.TemporaryDirectory() as d:
    log = McapLog(Path(d) / "calls.mcap", sc.epoch_ns, compact=True)
    world = World(sc, log)
    sched = LockstepScheduler(world.base_hz)
    world.schedule(sched)
    sched.run(5 * world.base_hz)
    v = next(x for x in world.vehicles if x.name == "quad")
    est, ekf = v.estimator, v.estimator.ekf
    f, w = np.array([0.1, 0.2, -9.8]), np.array([0.01, -0.02, 0.03])
    P0, nav0 = ekf.kf.P.copy(), ekf.nav.copy()
    aiding = [MagSample(ekf.t, np.array([20.0, 1.0, 40.0])), BaroSample(ekf.t, 96000.0)]

    def update():
        ekf.kf.P, ekf.nav = P0.copy(), nav0.copy()
        ekf.fuse_batch(aiding)

    def restore():
        ekf.kf.P, ekf.nav = P0.copy(), nav0.copy()

    parts = {
        "predict": (lambda: ekf.predict_mean(f, w, 1 / 60, ekf.t, w), 2000),
        "update (mag + baro)": (update, 2000),
        "restore state (in the update)": (restore, 2000),
        "estimate output": (lambda: ekf.state(ekf.t + 0.01), 5000),
        "IMU sample": (lambda: est.imu.measure_one(5.0, (0.1, 0.2, -9.8, 0.01, 0.02, 0.03), 1 / 240), 20000),
        "gyro attitude step": (lambda: est.attitude.step(5.0, (0.01, 0.02, 0.03), 1 / 240), 20000),
        "JSBSim step (quadrotor)": (lambda: v.plant.step(1), 1000),
    }
    for label, (fn, n) in parts.items():
        out[label] = min(timeit.repeat(fn, number=n, repeat=5, timer=time.process_time)) / n * 1e6
    log.close()
print(json.dumps(out))
"""


def measure(tree: Path) -> dict[str, float]:
    """Microseconds of CPU per call of each part, in code tree ``tree``."""
    res = subprocess.run([sys.executable, "-c", TIME], cwd=tree.resolve(), check=True, capture_output=True, text=True)
    return json.loads(res.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--before", type=Path, default=None, help="a code tree to time as well")
    args = ap.parse_args()
    now = measure(ROOT)
    before = measure(args.before) if args.before is not None else None
    print(f"{'part':32s} {'now [us]':>9s}" + (f" {'before [us]':>12s} {'before / now':>13s}" if before else ""))
    for label, us in now.items():
        line = f"{label:32s} {us:9.2f}"
        if before is not None:
            line += f" {before[label]:12.2f} {before[label] / us:13.2f}"
        print(line)


if __name__ == "__main__":
    main()
