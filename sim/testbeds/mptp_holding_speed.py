"""Holding at V_cor in closed loop, from run logs (seed 002 5.4): is the corrected orbit flown on time?

The first MPTP plan that commands airspeeds (``/<v>/plan`` with ``airspeeds``: a holding orbit at
V_cor, ``hold_speed_correction``) is judged while it is the newest plan, from SETTLE_S after its
issue: the mean true airspeed flown (``/<v>/truth/state``) against the orbit's commanded V_cor,
and, for every orbit vertex due in that window, the time the true horizontal track passes closest
to it less its due time (+ = late) and that closest distance. After the hold (the next plan, which
commands no airspeed): its planning speed (diagnostics ``tas_mps``) and the mean true airspeed
flown from SETTLE_S after it to the log's end, against the cruise speed. Frames: local-level NED
[m] of the log, times sim [s], speeds true airspeed [m/s].

``python -m sim.testbeds.mptp_holding_speed [SCENARIO.toml] --seeds 1-20 --out DIR`` flies the
scenario (default: the shipped ``scenarios/mptp/holding_speed.toml``) once per seed on its
estimator, keeps the logs in DIR and prints a Markdown row per seed and the worst over all.
"""

from __future__ import annotations

import argparse
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tomli_w

from sim import scenario as sc
from sim.replay.runlog import RunLog
from sim.runner import run_scenario

SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "mptp" / "holding_speed.toml"
SETTLE_S = 60.0  # after a plan's issue: the airspeed step and the first turn-in [s]
PASS_WINDOW_S = 60.0  # a vertex's closest approach is sought within this of its due time [s]


@dataclass(frozen=True)
class HoldFlight:
    """One holding flight: ``v_cor`` the orbit's commanded airspeed, ``tas_mean`` the true
    airspeed flown on it, ``lag_s`` / ``miss_m`` per orbit vertex (passed late / how close),
    ``setpoint_max_err`` the largest |follower demand - v_cor| while the hold was flown,
    ``cruise`` the follower's airspeed demand after the hold, ``after_planned`` the next
    plan's planning speed, ``after_tas_mean`` the true airspeed flown on it (NaN: no next plan)."""

    v_cor: float
    tas_mean: float
    lag_s: np.ndarray
    miss_m: np.ndarray
    setpoint_max_err: float
    cruise: float
    after_planned: float
    after_tas_mean: float


def hold_flight(log: RunLog, vehicle: str) -> HoldFlight:
    """The first hold of ``vehicle`` in ``log`` judged as in the module docstring."""
    plans = log.topic(f"/{vehicle}/plan").messages
    k = next((i for i, p in enumerate(plans) if p.get("airspeeds")), None)
    if k is None:
        raise ValueError(f"{vehicle}: no plan commands an airspeed (no hold at V_cor)")
    hold = plans[k]
    t_end = plans[k + 1]["t"] if k + 1 < len(plans) else float("inf")
    speeds = np.asarray(hold["airspeeds"], float)
    v_cor = float(speeds[-1])
    state = log.frame(f"/{vehicle}/truth/state")
    t = state.index.to_numpy()
    ne = state[["pos_ned.0", "pos_ned.1"]].to_numpy()
    tas = state["tas_mps"].to_numpy()
    on = (t >= hold["t"] + SETTLE_S) & (t < t_end)

    orbit = np.flatnonzero(speeds == v_cor)
    pos, due = np.asarray(hold["positions"], float)[orbit, :2], np.asarray(hold["times"], float)[orbit]
    judged = (due >= hold["t"] + SETTLE_S) & (due <= min(t_end, t[-1] - PASS_WINDOW_S))
    lag, miss = [], []
    for p, d in zip(pos[judged], due[judged], strict=True):
        near = np.flatnonzero(np.abs(t - d) <= PASS_WINDOW_S)
        j = near[np.argmin(np.linalg.norm(ne[near] - p, axis=1))]
        lag.append(t[j] - d)
        miss.append(float(np.linalg.norm(ne[j] - p)))

    sp = log.frame(f"/{vehicle}/ctrl/setpoint")["tas_mps"]
    flown = sp[(sp.index >= hold["t"]) & (sp.index < t_end)].to_numpy()
    after = sp[sp.index >= t_end].to_numpy()
    later = t >= t_end + SETTLE_S
    return HoldFlight(
        v_cor,
        float(tas[on].mean()),
        np.asarray(lag),
        np.asarray(miss),
        float(np.abs(flown - v_cor).max()),
        float(after[-1]) if len(after) else float("nan"),
        float(plans[k + 1]["diagnostics"]["tas_mps"]) if k + 1 < len(plans) else float("nan"),
        float(tas[later].mean()) if later.any() else float("nan"),
    )


def fly_seed(scenario: Path, seed: int, out: Path) -> Path:
    """Fly ``scenario`` with ``seed``; the log's path."""
    data = tomllib.loads(scenario.read_text())
    data["seed"] = seed
    path = out / f"{scenario.stem}_seed{seed}.mcap"
    run_scenario(sc.parse_scenario(data, str(scenario)), path, scenario_text=tomli_w.dumps(data))
    return path


def _seeds(text: str) -> list[int]:
    """Seeds from "1-20" or "1-3,5"."""
    out: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        out += list(range(int(lo), int(hi or lo) + 1))
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario", nargs="?", type=Path, default=SCENARIO)
    ap.add_argument("--seeds", default="1-20")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--vehicle", default="haps")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    cols = ["seed", "V_cor", "TAS flown - V_cor", "vertices", "lag min / max [s]", "miss max [m]", "after: planned at"]
    print("| " + " | ".join([*cols, "TAS flown"]) + " |\n" + "|---" * (len(cols) + 1) + "|")
    rows = []
    for seed in _seeds(args.seeds):
        h = hold_flight(RunLog(fly_seed(args.scenario, seed, args.out)), args.vehicle)
        rows.append(h)
        print(
            f"| {seed} | {h.v_cor:.3f} | {h.tas_mean - h.v_cor:+.3f} | {len(h.lag_s)} | {h.lag_s.min():+.1f} / "
            f"{h.lag_s.max():+.1f} | {h.miss_m.max():.1f} | {h.after_planned:.2f} | {h.after_tas_mean:.3f} |",
            flush=True,
        )
    dv = np.array([h.tas_mean - h.v_cor for h in rows])
    lag = np.concatenate([h.lag_s for h in rows])
    print(
        f"\n{len(rows)} seeds: TAS flown - V_cor {dv.min():+.3f} .. {dv.max():+.3f} m/s; vertex lag "
        f"{lag.min():+.1f} .. {lag.max():+.1f} s over {len(lag)} vertices; miss max "
        f"{max(h.miss_m.max() for h in rows):.1f} m; after the hold TAS flown "
        f"{min(h.after_tas_mean for h in rows):.3f} .. {max(h.after_tas_mean for h in rows):.3f} m/s"
    )


if __name__ == "__main__":
    main()
