"""INS/GNSS EKF step cost: analytic Jacobians against a finite-difference baseline, same run.

A 60 s multirotor flight with the default sensors is simulated once; its measurements are
recorded and replayed into a fresh filter for each Jacobian mode, timing each call:
- predict: one IMU sample (nominal mechanisation + Phi + filterpy ``predict``) [us];
- update_gnss / update_baro / update_mag: one fusion each [us];
- tick: ``push`` + ``update(t)`` for one 100 Hz tick, whatever arrived [us], and the implied
  real-time factor of the estimator alone.
Reported: medians, and the numeric/analytic ratio.

Then the per-vehicle component (``sim.estimation.sensor_estimator.SensorEstimator``) in closed
loop on the JSBSim plants through the lockstep scheduler (HAPS: trimmed at 18 km, autopilot +
L1, 10 Hz control; quadrotor: position hold under its controller at 60 Hz), each loop flown
twice in this run: on truth (``PerfectEstimator``) and on the component's estimate. Reported:
real-time factors, the component's wall time per simulated second [ms] split into IMU
sampling / aiding sensors / fusion (predict + update) / estimate output, and the baseline it
replaces measured in the same run: the per-IMU-sample filterpy path (one predict per 100 Hz
sample, sequential updates) per simulated second [ms] on recorded measurements.
JSON: benchmarks/results/ekf.json.

    python benchmarks/bench_ekf.py [--seconds 60] [--loop-seconds 120]
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
from sim.geodesy import GeoPoint  # noqa: E402
from sim.sensors.measurements import BaroSample, GnssFix, ImuSample, MagSample  # noqa: E402
from sim.sensors.suite import SensorSuite, SensorSuiteConfig  # noqa: E402
from sim.sensors.synthetic import Segment, generate  # noqa: E402

_CALLS = {ImuSample: "predict", GnssFix: "fuse_gnss", BaroSample: "fuse_baro", MagSample: "fuse_mag"}


def record(seconds: float):
    fl = generate(
        [
            Segment(seconds / 4, 0.0),
            Segment(seconds / 4, 5.0),
            Segment(seconds / 4, 5.0, 0.3),
            Segment(seconds / 4, 5.0, 0.0, 2.0),
        ],
        "multirotor",
        100.0,
        GeoPoint(47.0, 8.0, 400.0),
        (0.0, 0.0, -50.0),
    )
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


def closed_loop(kind: str, seconds: float, with_estimator: bool) -> dict:
    """One closed loop through the scheduler; the estimator's own wall time split by part."""
    from aircraft.haps.autopilot import HapsAutopilot, HapsGains
    from aircraft.quadrotor.controller import MultirotorController
    from aircraft.registry import get_airframe
    from guidance.l1 import L1Guidance
    from sim.core.setpoints import FixedWingSetpoint, MultirotorSetpoint
    from sim.estimation.sensor_estimator import SensorEstimator, SensorEstimatorConfig
    from sim.estimator import PerfectEstimator
    from sim.jsbsim_plant import InitialConditions, JSBSimPlant
    from sim.scheduler import LockstepScheduler, Stage

    origin = GeoPoint(47.0, 8.0, 0.0)
    af = get_airframe(kind)
    plant = JSBSimPlant(af.jsbsim_model, 1.0 / af.plant_hz, origin, af.folder)
    fw = af.kind == "fixed_wing"
    plant.initialise(InitialConditions(GeoPoint(47.0, 8.0, 18_000.0 if fw else 20.0), tas_mps=26.0 if fw else 0.0))
    if fw:
        plant.trim()
    cfg = SensorEstimatorConfig.for_kind(af.kind)
    est = (
        SensorEstimator(plant, cfg, np.random.default_rng(1), origin, plant.truth())
        if with_estimator
        else PerfectEstimator(plant)
    )
    dt = 1.0 / af.control_hz
    s0 = est.update(0.0)
    if fw:
        ctrl = HapsAutopilot(HapsGains.load())
        l1 = L1Guidance.for_airframe(ctrl)
        ctrl.reset(s0, throttle=plant["fcs/throttle-cmd-norm[0]"])
        a, b = s0.pos_ned.copy(), s0.pos_ned + [100_000.0, 0.0, 0.0]

        def control(t):
            e = est.update(t)
            plant.set_many(ctrl.update(e, FixedWingSetpoint(l1.update(e, a, b)[0], 18_000.0, 26.0), dt))
    else:
        ctrl = MultirotorController()
        ctrl.reset(s0, landed=False)
        sp = MultirotorSetpoint(pos_ned=s0.pos_ned + [10.0, 5.0, -5.0], yaw_rad=0.5)

        def control(t):
            plant.set_many(ctrl.update(est.update(t), sp, dt))

    parts = {"sense_total": 0.0, "aiding": 0.0, "fusion": 0.0, "estimate_output": 0.0}
    clock = time.perf_counter
    if with_estimator:

        def timed(key, fn):
            def w(*a):
                t0 = clock()
                r = fn(*a)
                parts[key] += clock() - t0
                return r

            return w

        est._poll_aiding = timed("aiding", est._poll_aiding)
        est._fuse = timed("fusion", est._fuse)
        sense = timed("sense_total", est.sense)
        estimate = timed("estimate_output", est.update)
    sched = LockstepScheduler(af.plant_hz)
    sched.add_plant("plant", af.plant_hz, plant.step)
    if with_estimator:
        sched.add_task("sense", cfg.sense_hz, Stage.SENSE, sense)
        sched.add_task("estimate", af.control_hz, Stage.ESTIMATE, estimate)
    sched.add_task("control", af.control_hz, Stage.CONTROL, control)
    t0 = clock()
    sched.run(round(seconds * af.plant_hz))
    wall = clock() - t0
    out = {"real_time_factor": seconds / wall, "wall_ms_per_sim_s": wall / seconds * 1e3}
    if with_estimator:
        ms = {k: v / seconds * 1e3 for k, v in parts.items()}
        ms["imu_sampling"] = ms["sense_total"] - ms["aiding"] - ms["fusion"]
        out["estimator_ms_per_sim_s"] = {k: round(v, 3) for k, v in ms.items()}
        out["estimator_ms_per_sim_s"]["total"] = round(ms["sense_total"] + ms["estimate_output"], 3)
        out["rates_hz"] = {"imu": cfg.sense_hz, "fusion": cfg.fusion_hz, "control": af.control_hz, "plant": af.plant_hz}
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--loop-seconds", type=float, default=60.0)
    args = ap.parse_args()
    fl, scfg, ticks = record(args.seconds)
    res = {"analytic": measure(fl, scfg, ticks, "analytic"), "numeric": measure(fl, scfg, ticks, "numeric")}
    base_ms = res["analytic"]["tick_us"] * scfg.imu.rate_hz / 1e3
    for kind in ("haps", "quadrotor"):  # best of 3 (the machine may be shared)
        truth = max(
            (closed_loop(kind, args.loop_seconds, False) for _ in range(3)), key=lambda r: r["real_time_factor"]
        )
        comp = max((closed_loop(kind, args.loop_seconds, True) for _ in range(3)), key=lambda r: r["real_time_factor"])
        comp_ms = comp["estimator_ms_per_sim_s"]["total"]
        res[f"closed_loop_{kind}"] = {
            "on_truth": truth,
            "on_sensor_estimator": comp,
            "baseline_per_sample_filterpy_ms_per_sim_s": round(base_ms, 3),
            "baseline_over_component": round(base_ms / comp_ms, 1),
        }
        print(kind, json.dumps(res[f"closed_loop_{kind}"]))
    res["numeric_over_analytic"] = {
        k: res["numeric"][k] / res["analytic"][k] for k in res["analytic"] if k.endswith("_us")
    }
    res["meta"] = {
        "sim_seconds": args.seconds,
        "imu_hz": scfg.imu.rate_hz,
        "states": 19,
        "python": platform.python_version(),
        "machine": platform.processor() or platform.machine(),
    }
    out = ROOT / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    (out / "ekf.json").write_text(json.dumps(res, indent=2))
    for mode in ("analytic", "numeric"):
        print(mode, {k: round(v, 1) for k, v in res[mode].items()})
    print("numeric / analytic", {k: round(v, 2) for k, v in res["numeric_over_analytic"].items()})


if __name__ == "__main__":
    main()
