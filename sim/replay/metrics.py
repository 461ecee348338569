"""Run metrics from vehicle traces: the same functions serve live runs and log replay.

All values SI: [m], [m/s], [rad] (reported in degrees where the key says ``_deg``), sim [s].
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from sim.replay.trace import VehicleTrace

# straight flight counts from this long after the last leg capture / carrot stop [s]
SETTLE_S = {"fixed_wing": 60.0, "multirotor": 2.0}


def straight_flight_mask(t: np.ndarray, turning: np.ndarray, settle_s: float) -> np.ndarray:
    """True where the vehicle is in settled straight flight: not capturing a leg, and at least
    ``settle_s`` since it last was."""
    turning = turning.astype(bool)
    last_turn = np.where(turning, t, -np.inf)
    last_turn = np.maximum.accumulate(last_turn)
    return ~turning & (t - last_turn >= settle_s)


def _stats(x: np.ndarray) -> dict[str, float]:
    if x.size == 0:
        return {"count": 0}
    return {"count": int(x.size), "mean": float(np.mean(x)), "rms": float(np.sqrt(np.mean(x * x))),
            "max_abs": float(np.max(np.abs(x)))}


def tracking_metrics(tr: VehicleTrace) -> dict:
    """Cross-track, altitude and airspeed holding in settled straight flight; bank extremes."""
    sp = tr.setpoint
    settled = straight_flight_mask(tr.t, sp["turning"], SETTLE_S[tr.kind])
    out = {
        "straight_fraction": float(settled.mean()) if settled.size else 0.0,
        "cross_track_m": _stats(sp["cross_track_m"][settled]),
        "altitude_error_m": _stats((tr.alt_msl_m - sp["altitude_m"])[settled]),
        "max_bank_deg": float(np.degrees(np.max(np.abs(tr.euler[:, 0])))) if len(tr.t) else 0.0,
        "finite": bool(np.isfinite(tr.pos_ned).all() and np.isfinite(tr.euler).all()),
    }
    if "tas_mps" in sp:
        out["airspeed_error_mps"] = _stats((tr.tas_mps - sp["tas_mps"])[settled])
    return out


def mission_metrics(tr: VehicleTrace) -> dict:
    return {
        "complete": tr.mission_complete,
        "waypoints_reached": len(tr.waypoint_times),
        "waypoints": tr.waypoints_total,
        "time_s": tr.complete_t,
    }


def latency_metrics(tr: VehicleTrace) -> dict:
    x = tr.plan_latency_s
    if x.size == 0:
        return {"count": 0}
    return {"count": int(x.size), "median_ms": float(np.median(x) * 1e3),
            "p95_ms": float(np.percentile(x, 95) * 1e3), "max_ms": float(np.max(x) * 1e3)}


def min_separation(a: VehicleTrace, b: VehicleTrace) -> dict:
    """Smallest 3-D distance between two vehicles at their common log times [m], and when."""
    common, ia, ib = np.intersect1d(a.t, b.t, assume_unique=True, return_indices=True)
    if common.size == 0:
        return {"distance_m": None, "t": None}
    d = np.linalg.norm(a.pos_ned[ia] - b.pos_ned[ib], axis=1)
    k = int(np.argmin(d))
    return {"distance_m": float(d[k]), "t": float(common[k])}


def run_metrics(traces: list[VehicleTrace]) -> dict:
    """Every metric of a run, as plain JSON-able values."""
    out: dict = {"vehicles": {}, "separation": {}}
    for tr in traces:
        out["vehicles"][tr.name] = {
            "mission": mission_metrics(tr), "tracking": tracking_metrics(tr),
            "planner_latency": latency_metrics(tr),
        }
    for a, b in itertools.combinations(traces, 2):
        out["separation"][f"{a.name}-{b.name}"] = min_separation(a, b)
    return out


def flatten(metrics: dict, prefix: str = "") -> dict[str, float | int | bool | None]:
    """Nested metrics as ``a.b.c`` keys (for tables and A/B comparison)."""
    flat: dict = {}
    for k, v in metrics.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            flat.update(flatten(v, key + "."))
        else:
            flat[key] = v
    return flat


def differing_keys(a: dict, b: dict) -> list[str]:
    """Keys where two metric sets differ (NaN equals NaN)."""
    fa, fb = flatten(a), flatten(b)
    diff = []
    for k in sorted(set(fa) | set(fb)):
        x, y = fa.get(k), fb.get(k)
        both_nan = isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y)
        if x != y and not both_nan:
            diff.append(k)
    return diff
