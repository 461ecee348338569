"""INS/GNSS EKF step cost: analytic Jacobians against a finite-difference baseline, same run.

A 60 s multirotor flight with the default sensors is simulated once; its measurements are
recorded and replayed into a fresh filter for each Jacobian mode, timing each call:
- predict: one IMU sample (nominal mechanisation + Phi + filterpy ``predict``) [us];
- update_gnss / update_baro / update_mag: one fusion each [us];
- tick: ``push`` + ``update(t)`` for one 100 Hz tick, whatever arrived [us], and the implied
  real-time factor of the estimator alone.
Reported: medians, and the numeric/analytic ratio. JSON: benchmarks/results/ekf.json.

    python benchmarks/bench_ekf.py [--seconds 60]
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sim.estimation.ins_ekf import InsEkf, InsEkfConfig  # noqa: E402
from sim.frames import GeoPoint  # noqa: E402
from sim.sensors.measurements import BaroSample, GnssFix, ImuSample, MagSample  # noqa: E402
from sim.sensors.suite import SensorSuite, SensorSuiteConfig  # noqa: E402
from sim.sensors.synthetic import Segment, generate  # noqa: E402

_CALLS = {ImuSample: "predict", GnssFix: "fuse_gnss", BaroSample: "fuse_baro", MagSample: "fuse_mag"}


def record(seconds: float):
    fl = generate([Segment(seconds / 4, 0.0), Segment(seconds / 4, 5.0), Segment(seconds / 4, 5.0, 0.3),
                   Segment(seconds / 4, 5.0, 0.0, 2.0)], "multirotor", 100.0, GeoPoint(47.0, 8.0, 400.0),
                  (0.0, 0.0, -50.0))
    suite = SensorSuite(SensorSuiteConfig(), np.random.default_rng(0))
    ticks = [(fl.t[k], suite.poll(fl.sample(k))) for k in range(len(fl))]
    return fl, suite.cfg, ticks


def measure(fl, scfg, ticks, jacobians: str) -> dict:
    ekf = InsEkf(InsEkfConfig.matching(scfg, jacobians=jacobians), fl.state(0), fl.origin)
    per: dict[str, list[float]] = {v: [] for v in _CALLS.values()}
    clock = time.perf_counter
    for _, meas in ticks:  # per-call costs
        for z in meas:
            name = _CALLS.get(type(z))
            if name is None:
                continue
            fn = getattr(ekf, name)
            t0 = clock()
            fn(z)
            per[name].append(clock() - t0)
    ekf = InsEkf(InsEkfConfig.matching(scfg, jacobians=jacobians), fl.state(0), fl.origin)
    t0 = clock()
    for t, meas in ticks:  # whole ticks through the Estimator protocol
        ekf.push(meas)
        ekf.update(t)
    wall = clock() - t0
    sim = ticks[-1][0] - ticks[0][0]
    out = {f"{k}_us": float(np.median(v) * 1e6) for k, v in per.items()}
    out |= {"tick_us": wall / len(ticks) * 1e6, "estimator_real_time_factor": sim / wall}
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=60.0)
    args = ap.parse_args()
    fl, scfg, ticks = record(args.seconds)
    res = {"analytic": measure(fl, scfg, ticks, "analytic"), "numeric": measure(fl, scfg, ticks, "numeric")}
    res["numeric_over_analytic"] = {k: res["numeric"][k] / res["analytic"][k] for k in res["analytic"]
                                    if k.endswith("_us")}
    res["meta"] = {"sim_seconds": args.seconds, "imu_hz": scfg.imu.rate_hz, "states": 19,
                   "python": platform.python_version(), "machine": platform.processor() or platform.machine()}
    out = ROOT / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    (out / "ekf.json").write_text(json.dumps(res, indent=2))
    for mode in ("analytic", "numeric"):
        print(mode, {k: round(v, 1) for k, v in res[mode].items()})
    print("numeric / analytic", {k: round(v, 2) for k, v in res["numeric_over_analytic"].items()})


if __name__ == "__main__":
    main()
