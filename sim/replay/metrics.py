"""Run metrics from vehicle traces: the same functions serve live runs and log replay.

All values SI: [m], [m/s], [rad] (reported in degrees where the key says ``_deg``), sim [s].
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import shapely

from sim.replay.trace import VehicleTrace

if TYPE_CHECKING:
    from sim.weather import WeatherService

FT = 0.3048


@dataclass(frozen=True, slots=True)
class MetricsWorld:
    """What metrics measure against besides the vehicles: map obstacles and geofences
    (``sim.core.threats`` types), scripted traffic objects (``sim.traffic.TrafficObject``) and
    the well-clear volume (horizontal radius, vertical half height [m]; default ASTM F3442
    small-UAS well clear, 2000 ft / 250 ft) and the NMAC cylinder (default RTCA DO-365 500 ft /
    100 ft)."""

    obstacles: tuple = ()
    geofences: tuple = ()
    objects: tuple = ()
    well_clear_h_m: float = 2000 * FT
    well_clear_v_m: float = 250 * FT
    weather: WeatherService | None = None  # the true storm field
    nmac_h_m: float = 500 * FT  # near mid-air collision cylinder: horizontal radius [m] ...
    nmac_v_m: float = 100 * FT  # ... and vertical half height [m] (default RTCA DO-365)

    @classmethod
    def from_scenario(cls, scenario) -> MetricsWorld:
        from sim.environment import geofence, obstacle_prism
        from sim.traffic import TrafficObject
        from sim.weather import WeatherService
        from sim.world import seed_streams, weather_seed

        alt0 = scenario.origin.altitude
        m = scenario.metrics
        weather = (
            WeatherService(scenario.weather, weather_seed(seed_streams(scenario.seed)[2]), scenario.origin_point)
            if scenario.weather is not None
            else None
        )
        return cls(
            tuple(obstacle_prism(o, alt0) for o in scenario.obstacle),
            tuple(geofence(g, alt0) for g in scenario.geofence),
            tuple(TrafficObject(o, scenario.origin_point) for o in scenario.object),
            m.well_clear_horizontal,
            m.well_clear_vertical,
            weather,
            m.nmac_horizontal,
            m.nmac_vertical,
        )


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
    return {
        "count": int(x.size),
        "mean": float(np.mean(x)),
        "rms": float(np.sqrt(np.mean(x * x))),
        "max_abs": float(np.max(np.abs(x))),
    }


def tracking_metrics(tr: VehicleTrace) -> dict:
    """True cross-track, altitude and airspeed holding in settled straight flight; bank
    extremes."""
    sp = tr.setpoint
    settled = straight_flight_mask(tr.t, sp["turning"], SETTLE_S[tr.kind])
    out = {
        "straight_fraction": float(settled.mean()) if settled.size else 0.0,
        "cross_track_m": _stats(tr.true_cross_track()[settled]),
        "altitude_error_m": _stats((tr.alt_msl_m - sp["altitude_m"])[settled]),
        "max_bank_deg": float(np.degrees(np.max(np.abs(tr.euler[:, 0])))) if len(tr.t) else 0.0,
        "finite": bool(np.isfinite(tr.pos_ned).all() and np.isfinite(tr.euler).all()),
    }
    if "tas_mps" in sp:
        out["airspeed_error_mps"] = _stats((tr.tas_mps - sp["tas_mps"])[settled])
    return out


def mission_metrics(tr: VehicleTrace) -> dict:
    """Mission progress, completion time [s] and the true path length flown [m] (to the end of
    the log)."""
    return {
        "complete": tr.mission_complete,
        "waypoints_reached": len(tr.waypoint_times),
        "waypoints": tr.waypoints_total,
        "time_s": tr.complete_t,
        "path_length_m": float(np.linalg.norm(np.diff(tr.pos_ned, axis=0), axis=1).sum()),
    }


def latency_metrics(tr: VehicleTrace) -> dict:
    """Wall-clock latency of the planner calls that made a new plan; ``cache_hits``: calls that
    kept the previous plan (not in the latency figures)."""
    x = tr.plan_latency_s
    if x.size == 0:
        return {"count": 0, "cache_hits": tr.plan_cache_hits}
    return {
        "count": int(x.size),
        "cache_hits": tr.plan_cache_hits,
        "median_ms": float(np.median(x) * 1e3),
        "p95_ms": float(np.percentile(x, 95) * 1e3),
        "max_ms": float(np.max(x) * 1e3),
    }


def common_times(a: VehicleTrace, b: VehicleTrace) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Log times [s] two vehicles share and their indices in each. Matched to the microsecond:
    a state's time is its plant's accumulated step, so a 120 Hz and a 240 Hz plant log the same
    tick as e.g. 0.1 and 0.09999999999999999."""
    _, ia, ib = np.intersect1d(
        np.round(a.t * 1e6).astype(np.int64),
        np.round(b.t * 1e6).astype(np.int64),
        assume_unique=True,
        return_indices=True,
    )
    return a.t[ia], ia, ib


def min_separation(a: VehicleTrace, b: VehicleTrace, world: MetricsWorld = MetricsWorld()) -> dict:
    """Smallest 3-D distance between two vehicles at their common log times [m], and when, with
    :func:`cylinder_separation` of the pair."""
    common, ia, ib = common_times(a, b)
    if common.size == 0:
        return {"distance_m": None, "t": None}
    d = np.linalg.norm(a.pos_ned[ia] - b.pos_ned[ib], axis=1)
    k = int(np.argmin(d))
    return {
        "distance_m": float(d[k]),
        "t": float(common[k]),
        **cylinder_separation(a.pos_ned[ia] - b.pos_ned[ib], world),
    }


def cylinder_separation(rel_ned: np.ndarray, world: MetricsWorld) -> dict:
    """From relative positions (N, 3) NED [m] at common times: the smallest horizontal and
    vertical separations [m] (each over the whole run), the vertical separation at the smallest
    horizontal one [m], whether the pair was ever inside the NMAC cylinder (``nmac``) and inside
    the well-clear volume (``lowc``), each horizontally and vertically at one same time."""
    h, v = np.hypot(rel_ned[:, 0], rel_ned[:, 1]), np.abs(rel_ned[:, 2])
    k = int(np.argmin(h))
    return {
        "min_horizontal_m": float(h[k]),
        "vertical_at_min_horizontal_m": float(v[k]),
        "min_vertical_m": float(v.min()),
        "nmac": bool(((h < world.nmac_h_m) & (v < world.nmac_v_m)).any()),
        "lowc": bool(((h < world.well_clear_h_m) & (v < world.well_clear_v_m)).any()),
    }


def _clearance(tr: VehicleTrace, footprint, up_min: float, up_max: float) -> np.ndarray:
    """3-D distance [m] from each position to a prism (0 inside)."""
    h = shapely.distance(shapely.points(tr.pos_ned[:, :2]), footprint)
    up = -tr.pos_ned[:, 2]
    v = np.maximum(np.maximum(up_min - up, up - up_max), 0.0)
    return np.hypot(h, v)


def _min_at(t: np.ndarray, d: np.ndarray) -> dict:
    if d.size == 0:
        return {"distance_m": None, "t": None}
    k = int(np.argmin(d))
    return {"distance_m": float(d[k]), "t": float(t[k])}


def obstacle_metrics(tr: VehicleTrace, world: MetricsWorld) -> dict:
    """Closest approach to every obstacle, and the smallest margin inside every keep-in geofence
    (negative: outside) or to every keep-out one, with times."""
    out = {
        f"obstacle.{o.id}": _min_at(tr.t, _clearance(tr, o.footprint, o.up_min_m, o.up_max_m)) for o in world.obstacles
    }
    for g in world.geofences:
        if g.keep_in:
            pts = shapely.points(tr.pos_ned[:, :2])
            h = shapely.distance(pts, g.area.exterior)
            h = np.where(shapely.contains(g.area, pts), h, -h)
            up = -tr.pos_ned[:, 2]
            margin = np.minimum(h, np.minimum(up - g.up_min_m, g.up_max_m - up))
        else:
            margin = _clearance(tr, g.area, g.up_min_m, g.up_max_m)
        m = _min_at(tr.t, margin)
        out[f"geofence.{g.id}"] = {
            "margin_m": m["distance_m"],
            "t": m["t"],
            "violated": bool(m["distance_m"] is not None and m["distance_m"] < 0),
        }
    return out


def object_metrics(tr: VehicleTrace, world: MetricsWorld) -> dict:
    """Closest approach to every scripted traffic object while it exists: 3-D distance from the
    vehicle to the object's sphere surface [m] (negative inside) and when, and
    :func:`cylinder_separation` of the vehicle and the object's centre."""
    out = {}
    for o in world.objects:
        live = tr.t >= o.appear
        rel = tr.pos_ned[live] - o.position(tr.t[live])
        d = np.linalg.norm(rel, axis=1) - o.radius_m
        out[f"object.{o.id}"] = _min_at(tr.t[live], d) | (cylinder_separation(rel, world) if len(rel) else {})
    return out


STORM_CHECK_S = 10.0  # storms are checked against the track this often [s] ...
STORM_CHECKS_MIN = 200  # ... or more often, so that a short run is checked this many times


def storm_metrics(tr: VehicleTrace, world: MetricsWorld) -> dict:
    """Horizontal distance to the nearest TRUE storm cell at the vehicle's position and time
    (checked every ``STORM_CHECK_S``, at least ``STORM_CHECKS_MIN`` times per run; 0 inside a
    cell), its minimum with time, and the time spent inside cells (storms reach from the ground
    to above the HAPS)."""
    if world.weather is None or not len(tr.t):
        return {}
    step = min(STORM_CHECK_S, max(float(tr.t[-1] - tr.t[0]), 1e-9) / STORM_CHECKS_MIN)
    idx = np.unique(np.searchsorted(tr.t, np.arange(tr.t[0], tr.t[-1] + 1e-9, step)).clip(0, len(tr.t) - 1))
    dist = np.full(len(idx), np.inf)
    for j, i in enumerate(idx):
        cells = world.weather.truth(float(tr.t[i])).cells
        if cells:
            dist[j] = float(np.min(shapely.distance(shapely.points(tr.pos_ned[i, :2]), np.array(cells, dtype=object))))
    k = int(np.argmin(dist))
    spacing = float(np.mean(np.diff(tr.t[idx]))) if len(idx) > 1 else step  # per check [s]
    return {
        "min_distance_m": float(dist[k]) if np.isfinite(dist[k]) else None,
        "t": float(tr.t[idx[k]]),
        "time_inside_s": float(np.sum(dist == 0.0) * spacing),
    }


def well_clear_losses(a: VehicleTrace, b: VehicleTrace, world: MetricsWorld) -> list[dict]:
    """Intervals where two vehicles are inside each other's well-clear volume: start, end [s] and
    the smallest 3-D distance in it [m]."""
    common, ia, ib = common_times(a, b)
    d = a.pos_ned[ia] - b.pos_ned[ib]
    inside = (np.hypot(d[:, 0], d[:, 1]) < world.well_clear_h_m) & (np.abs(d[:, 2]) < world.well_clear_v_m)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], inside.astype(int), [0]])))
    dist = np.linalg.norm(d, axis=1)
    return [
        {"start": float(common[s]), "end": float(common[e - 1]), "min_distance_m": float(dist[s:e].min())}
        for s, e in zip(edges[::2], edges[1::2], strict=False)
    ]


def control_effort(tr: VehicleTrace) -> dict[str, float]:
    """RMS of each commanded JSBSim property over the run (JSBSim units)."""
    return {k: float(np.sqrt(np.nanmean(v * v))) for k, v in sorted(tr.commands.items()) if np.isfinite(v).any()}


def estimation_metrics(tr: VehicleTrace) -> dict:
    """Estimate against truth at the log ticks: RMS errors per NED axis, the fraction of errors
    inside the 3-sigma bounds, and the mean NEES of position+velocity (diagonal covariance;
    consistent filter: about 6)."""
    if tr.est_pos_ned is None or len(tr.est_pos_ned) != len(tr.t) or not len(tr.t):
        return {}
    ep, ev = tr.est_pos_ned - tr.pos_ned, tr.est_vel_ned - _truth_velocity(tr)
    out = {
        "pos_rms_m": np.sqrt(np.mean(ep * ep, axis=0)).tolist(),
        "vel_rms_mps": np.sqrt(np.mean(ev * ev, axis=0)).tolist(),
    }
    sp, sv = tr.sigma3_pos, tr.sigma3_vel
    if sp is not None and sv is not None and len(sp) == len(tr.t):
        out["pos_within_3sigma"] = np.mean(np.abs(ep) <= sp, axis=0).tolist()
        out["vel_within_3sigma"] = np.mean(np.abs(ev) <= sv, axis=0).tolist()
        nees = np.sum((ep / (sp / 3.0)) ** 2, axis=1) + np.sum((ev / (sv / 3.0)) ** 2, axis=1)
        out["nees_mean"] = float(np.mean(nees))
    return out


def _truth_velocity(tr: VehicleTrace) -> np.ndarray:
    return tr.truth_vel_ned if tr.truth_vel_ned is not None else np.gradient(tr.pos_ned, tr.t, axis=0)


def run_metrics(traces: list[VehicleTrace], world: MetricsWorld = MetricsWorld()) -> dict:
    """Every metric of a run, as plain JSON-able values."""
    out: dict = {"vehicles": {}, "separation": {}}
    for tr in traces:
        out["vehicles"][tr.name] = {
            "mission": mission_metrics(tr),
            "tracking": tracking_metrics(tr),
            "planner_latency": latency_metrics(tr),
            "clearance": obstacle_metrics(tr, world) | object_metrics(tr, world),
            "control_effort": control_effort(tr),
            "estimation": estimation_metrics(tr),
            "storms": storm_metrics(tr, world),
        }
    for a, b in itertools.combinations(traces, 2):
        losses = well_clear_losses(a, b, world)
        out["separation"][f"{a.name}-{b.name}"] = {
            **min_separation(a, b, world),
            "well_clear_losses": len(losses),
            "well_clear_loss_events": losses,
        }
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
