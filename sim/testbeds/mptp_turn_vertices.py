"""Cross-track at the MPTP plan's vertices, from run logs (seed 002 ch. 5: are the plans flown?).

For every plan the MPTP logged (``/<v>/plan``), its corners (interior vertices where the plan
turns by at least MIN_TURN_DEG) that fell due while it was the newest plan, at least SETTLE_S
before the next plan and before the track ends (a short flight leaves its last plan's later
corners unflown): the closest approach [m] of the true horizontal track flown while it was
the newest plan, signed + on the inside of the corner (the side the plan turns to: a cut corner)
and - on the outside. Frames: local-level NED [m] of the log.

``python -m sim.testbeds.mptp_turn_vertices SCENARIO.toml ... --seeds 1-20 --models simple
simulated --out DIR`` flies every scenario with each seed and ``turn_model`` (the scenario's
planner options otherwise unchanged; ``--acceptance`` overrides the MPTP vehicles' acceptance
radius, ``--duration`` the sim time, ``--since`` leaves out the plans issued before this sim
time [s]), keeps the logs in DIR and prints a Markdown table per
scenario and model (``--per-seed``: also a row per seed): corners, median |xte|, 95th
percentile of the cut, largest cut, largest outside pass [m], the same two without each plan's
start turn (vertex_cross_track) and along the estimated track the follower flew on (the true
track's cross-track less the navigation error), the missions completed, and the yardstick: the
largest distance of the true track from the midpoint of a straight leg (midleg_cross_track).

Controlled factors (the experiment that isolates why turns are flown wide, docs/mptp.md):
``--estimator perfect`` (ideal sensors instead of the EKF), ``--wind N,E`` (the steady wind [m/s]
in place of the scenario's), ``--l1-period S`` (the L1 period [s] instead of the airframe's).
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import math
import tomllib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from unittest import mock

import numpy as np
import tomli_w

from guidance.l1 import L1Guidance
from sim import scenario as sc
from sim.mcap_read import read_info, read_topic
from sim.runner import run_scenario

MIN_TURN_DEG = 1.0  # a vertex turning less is not a corner
SETTLE_S = 60.0  # corners due later than this before the next plan are left out [s]
MIN_LEG_M = 500.0  # a leg this long or longer is a straight leg (written-out turns have short ones) [m]


Plans = list[tuple[float, np.ndarray, np.ndarray]]  # (issue time [s], vertices (N, 2) [m], due times (N,) [s])


def _logged(log: str | Path, vehicle: str, track_of: str = "truth") -> tuple[Plans, list[dict], np.ndarray, np.ndarray]:
    """``vehicle``'s logged plans (and their messages) and its ``track_of`` track: times (K,) [s]
    and horizontal positions (K, 2) NED [m]."""
    msgs = read_topic(log, f"/{vehicle}/plan")
    plans = [(t, np.asarray(m["positions"], float)[:, :2], np.asarray(m["times"], float)) for t, m in msgs]
    track = read_topic(log, f"/{vehicle}/{track_of}/state")
    tt, xy = np.array([t for t, _ in track]), np.array([m["pos_ned"][:2] for _, m in track])
    return plans, [m for _, m in msgs], tt, xy


def vertex_cross_track(
    log: str | Path, vehicle: str, start_turns: bool = True, track_of: str = "truth", since_s: float = 0.0
) -> np.ndarray:
    """Signed closest approach [m] of the ``track_of`` track ("truth", or "est": the estimate the
    follower flew on) to each flown corner (see module doc) of the plans issued from ``since_s``
    [s] on; without ``start_turns`` the written-out turn each plan begins with (its leading legs
    with a nonzero turn rate, after the lead-in leg of a plan that has one, diagnostics
    ``start_lead_s`` > 0) is left out."""
    plans, msgs, tt, xy = _logged(log, vehicle, track_of)
    skip = []
    for (t, pts, _), m in zip(plans, msgs, strict=True):
        first = int(m.get("diagnostics", {}).get("start_lead_s", 0.0) > 0.0)
        rates = np.asarray(m.get("turn_rates") or [0.0])[first:] != 0.0
        start = 0 if start_turns else first + int(np.argmin(np.r_[rates, False]))
        skip.append(start if t >= since_s else len(pts))
    return corner_cross_track(plans, tt, xy, skip)


def _while_newest(
    plans: Plans, tt: np.ndarray, xy: np.ndarray
) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray, float]]:
    """Per plan, in order: its vertices, due times, the track ``xy`` flown while it was the newest
    plan (possibly empty), and the latest due time [s] that counts: SETTLE_S before the next plan
    and not after the track's last time."""
    ends = [t for t, _, _ in plans[1:]] + [math.inf]
    last = float(tt[-1]) if len(tt) else -math.inf
    for (t0, pts, due), t1 in zip(plans, ends, strict=True):
        yield pts, due, xy[(tt >= t0) & (tt < t1)], min(t1 - SETTLE_S, last)


def corner_cross_track(plans: Plans, tt: np.ndarray, xy: np.ndarray, skip: list[int] | None = None) -> np.ndarray:
    """Signed closest approach [m] of the track ``xy`` (K, 2) [m] at times ``tt`` (K,) [s] to the
    corners of ``plans`` (issue time [s], vertices (N, 2) [m], due times (N,) [s]), in time
    order; + inside the corner, - outside (see module doc); corners due after the track's last
    time are left out. ``skip``: per plan, the corners up to this vertex index are left out
    (default none)."""
    out: list[float] = []
    for (pts, due, seg, due_by), first in zip(_while_newest(plans, tt, xy), skip or [0] * len(plans), strict=True):
        if len(pts) < 3 or not len(seg):
            continue
        for k in range(max(1, first + 1), len(pts) - 1):
            a, b = pts[k] - pts[k - 1], pts[k + 1] - pts[k]
            na, nb = np.linalg.norm(a), np.linalg.norm(b)
            if na < 1e-6 or nb < 1e-6 or due[k] > due_by:
                continue
            inward = b / nb - a / na
            if np.linalg.norm(inward) < 2.0 * math.sin(0.5 * math.radians(MIN_TURN_DEG)):
                continue
            r = seg - pts[k]
            j = int(np.argmin(np.einsum("ij,ij->i", r, r)))
            out.append(float(np.linalg.norm(r[j]) * np.sign(r[j] @ inward)))
    return np.array(out)


def midleg_cross_track(plans: Plans, tt: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Distance [m] of the track ``xy`` (K, 2) at times ``tt`` (K,) [s] from the midpoint of each
    straight leg (at least MIN_LEG_M long) of ``plans`` (as :func:`corner_cross_track`), for the
    midpoints due while the plan was the newest, SETTLE_S before the next one and before the
    track ends: how closely a straight leg is flown, the yardstick of the corners' cross-track."""
    out: list[float] = []
    for pts, due, seg, due_by in _while_newest(plans, tt, xy):
        if not len(seg):
            continue
        for k in range(len(pts) - 1):
            if np.linalg.norm(pts[k + 1] - pts[k]) < MIN_LEG_M or 0.5 * (due[k] + due[k + 1]) > due_by:
                continue
            r = seg - 0.5 * (pts[k] + pts[k + 1])
            out.append(float(np.sqrt(np.einsum("ij,ij->i", r, r).min())))
    return np.array(out)


def leg_cross_track(log: str | Path, vehicle: str) -> np.ndarray:
    """:func:`midleg_cross_track` of the true track against every plan ``vehicle`` logged."""
    plans, _, tt, xy = _logged(log, vehicle)
    return midleg_cross_track(plans, tt, xy)


@dataclass(frozen=True, slots=True)
class Factors:
    """The experiment's controlled factors (None: as the scenario and airframe have them):
    ``estimator`` ("ekf" or "perfect"), a steady ``wind_ne`` (north, east) [m/s] in place of the
    scenario's steady components, the L1 period ``l1_period_s`` [s]."""

    estimator: str | None = None
    wind_ne: tuple[float, float] | None = None
    l1_period_s: float | None = None

    def tag(self) -> str:
        """File-name suffix naming the factors set."""
        out = "" if self.estimator is None else f"_{self.estimator}"
        out += "" if self.wind_ne is None else f"_w{self.wind_ne[0]:g},{self.wind_ne[1]:g}"
        return out + ("" if self.l1_period_s is None else f"_l1p{self.l1_period_s:g}")


def _variant(data: dict, seed: int, model: str, accept: float | None, duration: float | None, factors: Factors) -> dict:
    out = copy.deepcopy(data)
    out["seed"] = seed
    if duration is not None:
        out["duration"] = duration
    if factors.wind_ne is not None:
        out.setdefault("wind", {}).update(north=factors.wind_ne[0], east=factors.wind_ne[1])
    for v in out["vehicle"]:
        if factors.estimator is not None:
            v["estimator"] = factors.estimator
        if v.get("planner", {}).get("type") == "mptp":
            v["planner"].setdefault("options", {})["turn_model"] = model
            if accept is not None:
                v["mission"]["acceptance_radius"] = accept
    return out


@contextlib.contextmanager
def _l1_period(period_s: float | None) -> Iterator[None]:
    """Every L1 follower built inside the block runs at ``period_s`` [s] (None: the airframe's)."""
    if period_s is None:
        yield
        return
    built = L1Guidance.for_airframe.__func__  # type: ignore[attr-defined]

    def with_period(cls: type[L1Guidance], controller: object) -> L1Guidance:
        l1 = built(cls, controller)
        return cls(period_s, l1.damping, l1.roll_limit_rad)

    with mock.patch.object(L1Guidance, "for_airframe", classmethod(with_period)):
        yield


def fly(
    scenario: Path,
    seed: int,
    model: str,
    out_dir: Path,
    accept: float | None = None,
    duration: float | None = None,
    factors: Factors = Factors(),
) -> tuple[Path, bool]:
    """Fly ``scenario`` with ``seed``, ``turn_model`` = ``model``, the MPTP vehicles' acceptance
    radius ``accept`` [m], ``duration`` [s] (None: the scenario's) and the experiment's
    ``factors``; the log and whether every mission completed."""
    data = _variant(tomllib.loads(scenario.read_text()), seed, model, accept, duration, factors)
    tag = ("" if accept is None else f"_a{accept:g}") + factors.tag()
    path = out_dir / f"{scenario.stem}_{model}{tag}_s{seed}.mcap"
    if not path.exists():
        with _l1_period(factors.l1_period_s):
            run_scenario(sc.parse_scenario(data, str(scenario)), path, scenario_text=tomli_w.dumps(data))
    result = read_info(path).metadata.get("result", {})
    return path, all(v == "True" for k, v in result.items() if k.endswith(".mission_complete"))


def _cut_and_outside(x: np.ndarray) -> tuple[float, float]:
    """Largest cut and largest outside pass [m] (>= 0) of signed cross-tracks ``x`` (+ inside)."""
    return max(0.0, float(x.max(initial=0.0))), max(0.0, -float(x.min(initial=0.0)))


def _seeds(text: str) -> list[int]:
    """Seeds from "1-20" or "1-3,5" (ranges and single seeds, comma separated)."""
    out: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        out += range(int(lo), int(hi or lo) + 1)
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenarios", nargs="+", type=Path)
    ap.add_argument("--seeds", default="1-20")
    ap.add_argument("--models", nargs="+", default=["simple", "simulated"])
    ap.add_argument("--acceptance", type=float, default=None, help="acceptance radius [m] (default: the scenario's)")
    ap.add_argument("--duration", type=float, default=None, help="sim time [s] (default: the scenario's)")
    ap.add_argument("--estimator", choices=["ekf", "perfect"], default=None, help="default: the scenario's")
    ap.add_argument("--wind", default=None, help="steady wind N,E [m/s] (replaces the scenario's)")
    ap.add_argument("--l1-period", type=float, default=None, help="L1 period [s] (default: the airframe's)")
    ap.add_argument("--out", type=Path, default=Path("logs/mptp_turn_vertices"))
    ap.add_argument("--per-seed", action="store_true", help="also a row per seed")
    ap.add_argument("--since", type=float, default=0.0, help="only the plans issued from this sim time [s] on")
    args = ap.parse_args(argv)
    wind = None if args.wind is None else tuple(float(v) for v in args.wind.split(","))
    if wind is not None and len(wind) != 2:
        ap.error(f"--wind: expected N,E in m/s, got {args.wind!r}")
    factors = Factors(args.estimator, wind, args.l1_period)
    args.out.mkdir(parents=True, exist_ok=True)
    cols = ["scenario", "seeds", "acceptance [m]", "turn model", "runs completed", "corners", "median abs [m]"]
    cols += ["cut p95 [m]", "largest cut [m]", "largest outside [m]", "later turns: largest cut [m]"]
    cols += ["largest outside [m]", "estimated track: largest cut [m]", "largest outside [m]"]
    cols += ["straight legs: midpoints", "mid-leg largest abs [m]"]
    print("| " + " | ".join(cols) + " |\n|" + "---|" * len(cols))
    for scenario in args.scenarios:
        for model in args.models:
            runs: list[tuple[int, bool, np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
            for seed in _seeds(args.seeds):
                path, ok = fly(scenario, seed, model, args.out, args.acceptance, args.duration, factors)
                every = vertex_cross_track(path, "haps", since_s=args.since)
                later = vertex_cross_track(path, "haps", start_turns=False, since_s=args.since)
                est = vertex_cross_track(path, "haps", track_of="est", since_s=args.since)
                runs.append((seed, ok, every, later, est, leg_cross_track(path, "haps")))
                if args.per_seed:
                    print(_row(scenario.stem, str(seed), args.acceptance, model, runs[-1:]), flush=True)
            print(_row(scenario.stem, args.seeds, args.acceptance, model, runs), flush=True)


def _row(
    stem: str,
    seeds: str,
    accept: float | None,
    model: str,
    runs: list[tuple[int, bool, np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
) -> str:
    """One Markdown table row over ``runs`` (seed, mission completed, cross-tracks [m] of every
    corner, of the later turns, of the estimated track, distances from the straight legs'
    midpoints)."""
    x, y, e, m = (np.concatenate([r[k] for r in runs]) for k in (2, 3, 4, 5))
    cut = np.maximum(x, 0.0)
    row = [stem, seeds, accept or "shipped", model, f"{sum(r[1] for r in runs)}/{len(runs)}", len(x)]
    row += [f"{v:.1f}" for v in (np.median(np.abs(x)), np.percentile(cut, 95), *_cut_and_outside(x))]
    row += [f"{v:.1f}" for z in (y, e) for v in _cut_and_outside(z)]
    row += [len(m), f"{m.max(initial=0.0):.1f}"]
    return "| " + " | ".join(map(str, row)) + " |"


if __name__ == "__main__":
    main()
