"""One vehicle's run metrics, folded in chunk by chunk (:class:`VehicleMetrics`).

All values SI: [m], [m/s], [rad] (reported in degrees where the key says ``_deg``), sim [s].
"""

from __future__ import annotations

import math

import numpy as np
import shapely

from sim.core.threats import StormSnapshot
from sim.replay.metrics_world import MetricsWorld
from sim.replay.reducers import CylinderSeparation, LatencySketch, RunningMin, RunningStats
from sim.replay.trace import VehicleTrace

SETTLE_S = {"fixed_wing": 60.0, "multirotor": 2.0}


def straight_flight_mask(
    t: np.ndarray, turning: np.ndarray, settle_s: float, last_turn_s: float = -math.inf
) -> np.ndarray:
    """True where the vehicle is in settled straight flight: not capturing a leg, and at least
    ``settle_s`` since it last was (``last_turn_s``: the last turning sample before ``t`` [s])."""
    turning = turning.astype(bool)
    last_turn = np.maximum.accumulate(np.where(turning, t, last_turn_s))
    return ~turning & (t - last_turn >= settle_s)


def _clearance(pos_ned: np.ndarray, footprint, up_min: float, up_max: float) -> np.ndarray:
    """3-D distance [m] from each position to a prism (0 inside)."""
    h = shapely.distance(shapely.points(pos_ned[:, :2]), footprint)
    up = -pos_ned[:, 2]
    v = np.maximum(np.maximum(up_min - up, up - up_max), 0.0)
    return np.hypot(h, v)


def _keep_in_margin(pos_ned: np.ndarray, g) -> np.ndarray:
    """Smallest margin [m] inside a keep-in geofence, negative outside."""
    pts = shapely.points(pos_ned[:, :2])
    h = shapely.distance(pts, g.area.exterior)
    h = np.where(shapely.contains(g.area, pts), h, -h)
    up = -pos_ned[:, 2]
    return np.minimum(h, np.minimum(up - g.up_min_m, g.up_max_m - up))


def storm_distance(snapshot: StormSnapshot, pos_ned: np.ndarray) -> float:
    """Euclidean distance [m] from ``pos_ned`` (NED [m]) to the nearest cell of ``snapshot``, each
    the prism of its polygon between its base and top (0 inside one; inf without cells): the
    horizontal distance to the polygon and the vertical one to the extent, combined."""
    if not snapshot.cells:
        return math.inf
    h = shapely.distance(shapely.points(pos_ned[:2]), np.array(snapshot.cells, dtype=object))
    ext = snapshot.extents()
    up = -float(pos_ned[2])
    v = np.maximum(0.0, np.maximum(ext[:, 0] - up, up - ext[:, 1]))
    return float(np.min(np.hypot(h, v)))


STORM_CHECK_S = 10.0  # storms are checked against the track this often [s] ...
STORM_CHECKS_MIN = 200  # ... or more often, so that a run of the planned duration is checked this many times


class VehicleMetrics:
    """One vehicle's metrics, folded in chunk by chunk (:meth:`add`); memory does not grow with
    the run's duration (only with the number of well-clear losses, obstacles and the like).

    - tracking: true cross-track, altitude and airspeed errors in settled straight flight (count,
      mean, RMS, largest magnitude), the straight fraction, the largest bank [deg], finiteness;
    - mission: waypoints reached, completion time [s], true path length flown [m];
    - planner latency of the calls that made a new plan (:class:`LatencySketch`), cache hits;
    - clearance: closest approach to every obstacle and scripted object, smallest margin to every
      geofence, with times;
    - control effort: RMS of each commanded JSBSim property (JSBSim units);
    - estimation: RMS estimate errors per NED axis, fraction inside the 3-sigma bounds, mean NEES
      of position+velocity (diagonal covariance; a consistent filter gives about 6);
    - storms: distance to the nearest TRUE storm cell (a prism, :func:`storm_distance`), checked
      every ``STORM_CHECK_S`` (at least ``STORM_CHECKS_MIN`` times over the planned duration), its
      minimum and the time inside cells.
    """

    def __init__(self, name: str, kind: str, world: MetricsWorld):
        self.name, self.kind, self.world = name, kind, world
        self.samples = 0
        self.settled = 0
        self.last_turn_s = -math.inf
        self.errors = {"cross_track_m": RunningStats(), "altitude_error_m": RunningStats()}
        self.max_bank_rad = 0.0
        self.finite = True
        self.waypoints_total = 0
        self.waypoints_reached = 0
        self.complete_t: float | None = None
        self.path_length_m = 0.0
        self.last_pos: np.ndarray | None = None
        self.latency = LatencySketch()
        self.cache_hits = 0
        self.clearance = {f"obstacle.{o.id}": RunningMin() for o in world.obstacles}
        self.fences = {g.id: RunningMin() for g in world.geofences}
        self.objects = {
            o.id: (
                RunningMin(),
                CylinderSeparation(world.nmac_h_m, world.nmac_v_m, world.well_clear_h_m, world.well_clear_v_m),
            )
            for o in world.objects
        }
        self.effort: dict[str, list[float]] = {}  # property -> [sum of squares, non-NaN count, finite count]
        self.effort_props: tuple[str, ...] = ()
        self.est = {"pos": np.zeros(3), "vel": np.zeros(3), "pos_in": np.zeros(3), "vel_in": np.zeros(3)}
        self.est_samples = self.sigma_samples = 0
        self.nees_sum = 0.0
        self.storm_next_s: float | None = None
        self.storm = RunningMin()
        self.storm_checks = self.storm_inside = 0
        self.storm_first_s = self.storm_last_s = 0.0

    def add(self, tr: VehicleTrace) -> None:
        """Fold in a chunk of the vehicle's trace (its samples follow the previous chunk's)."""
        self.waypoints_total = tr.waypoints_total
        self.waypoints_reached += len(tr.waypoint_times)
        self.complete_t = tr.complete_t if tr.complete_t is not None else self.complete_t
        self.latency.add(tr.plan_latency_s)
        self.cache_hits += tr.plan_cache_hits
        if not len(tr.t):
            return
        self.samples += len(tr.t)
        self._tracking(tr)
        steps = np.diff(np.vstack([tr.pos_ned[:1] if self.last_pos is None else self.last_pos, tr.pos_ned]), axis=0)
        self.path_length_m += float(np.linalg.norm(steps, axis=1).sum())
        self.last_pos = tr.pos_ned[-1:].copy()
        self._clearance(tr)
        self._effort(tr)
        self._estimation(tr)
        self._storms(tr)

    def _tracking(self, tr: VehicleTrace) -> None:
        sp = tr.setpoint
        turning = sp["turning"].astype(bool)
        settled = straight_flight_mask(tr.t, turning, SETTLE_S[tr.kind], self.last_turn_s)
        if turning.any():
            self.last_turn_s = float(tr.t[turning][-1])
        self.settled += int(settled.sum())
        self.errors["cross_track_m"].add(tr.true_cross_track()[settled])
        self.errors["altitude_error_m"].add((tr.alt_msl_m - sp["altitude_m"])[settled])
        if "tas_mps" in sp:
            self.errors.setdefault("airspeed_error_mps", RunningStats()).add((tr.tas_mps - sp["tas_mps"])[settled])
        self.max_bank_rad = max(self.max_bank_rad, float(np.max(np.abs(tr.euler[:, 0]))))
        self.finite &= bool(np.isfinite(tr.pos_ned).all() and np.isfinite(tr.euler).all())

    def _clearance(self, tr: VehicleTrace) -> None:
        for o in self.world.obstacles:
            self.clearance[f"obstacle.{o.id}"].add(tr.t, _clearance(tr.pos_ned, o.footprint, o.up_min_m, o.up_max_m))
        for g in self.world.geofences:
            margin = (
                _keep_in_margin(tr.pos_ned, g) if g.keep_in else _clearance(tr.pos_ned, g.area, g.up_min_m, g.up_max_m)
            )
            self.fences[g.id].add(tr.t, margin)
        for o in self.world.objects:
            live = tr.t >= o.appear
            rel = tr.pos_ned[live] - o.position(tr.t[live])
            closest, cylinder = self.objects[o.id]
            closest.add(tr.t[live], np.linalg.norm(rel, axis=1) - o.radius_m)
            cylinder.add(tr.t[live], rel)

    def _effort(self, tr: VehicleTrace) -> None:
        for p, v in tr.commands.items():
            acc = self.effort.setdefault(p, [0.0, 0, 0])
            ok = ~np.isnan(v)
            acc[0] += float(np.sum(v[ok] * v[ok]))
            acc[1] += int(ok.sum())
            acc[2] += int(np.isfinite(v).sum())
        self.effort_props = tuple(tr.commands)

    def _estimation(self, tr: VehicleTrace) -> None:
        if tr.est_pos_ned is None or tr.est_vel_ned is None or tr.truth_vel_ned is None:
            return
        if len(tr.est_pos_ned) != len(tr.t):
            return
        self.est_samples += len(tr.t)
        ep, ev = tr.est_pos_ned - tr.pos_ned, tr.est_vel_ned - tr.truth_vel_ned
        self.est["pos"] += np.sum(ep * ep, axis=0)
        self.est["vel"] += np.sum(ev * ev, axis=0)
        sp, sv = tr.sigma3_pos, tr.sigma3_vel
        if sp is not None and sv is not None and len(sp) == len(tr.t):
            self.sigma_samples += len(tr.t)
            self.est["pos_in"] += np.sum(np.abs(ep) <= sp, axis=0)
            self.est["vel_in"] += np.sum(np.abs(ev) <= sv, axis=0)
            nees = np.sum((ep / (sp / 3.0)) ** 2, axis=1) + np.sum((ev / (sv / 3.0)) ** 2, axis=1)
            self.nees_sum += float(np.sum(nees))

    def _storms(self, tr: VehicleTrace) -> None:
        weather = self.world.weather
        if weather is None:
            return
        step = min(STORM_CHECK_S, max(self.world.duration_s, 1e-9) / STORM_CHECKS_MIN)
        if self.storm_next_s is None:
            self.storm_next_s = float(tr.t[0])
        for i in range(len(tr.t)):  # the first sample at or after each check time
            t = float(tr.t[i])
            if t < self.storm_next_s:
                continue
            self.storm_next_s += step * (math.floor((t - self.storm_next_s) / step) + 1)
            d = storm_distance(weather.truth(t), tr.pos_ned[i])
            self.storm.add(np.array([t]), np.array([d]))
            self.storm_inside += d == 0.0
            self.storm_first_s = t if not self.storm_checks else self.storm_first_s
            self.storm_last_s = t
            self.storm_checks += 1

    def result(self) -> dict:
        """The metrics so far, as plain JSON-able values."""
        return {
            "mission": {
                "complete": self.complete_t is not None,
                "waypoints_reached": self.waypoints_reached,
                "waypoints": self.waypoints_total,
                "time_s": self.complete_t,
                "path_length_m": self.path_length_m,
            },
            "tracking": {
                "straight_fraction": self.settled / self.samples if self.samples else 0.0,
                **{k: v.result() for k, v in self.errors.items()},
                "max_bank_deg": math.degrees(self.max_bank_rad),
                "finite": self.finite,
            },
            "planner_latency": self._latency(),
            "clearance": self._clearance_result(),
            "control_effort": {
                p: math.sqrt(self.effort[p][0] / self.effort[p][1])
                for p in sorted(self.effort_props)
                if self.effort[p][2] and self.effort[p][1]
            },
            "estimation": self._estimation_result(),
            "storms": self._storm_result(),
        }

    def _latency(self) -> dict:
        lat = self.latency
        if not lat.count:
            return {"count": 0, "cache_hits": self.cache_hits}
        return {
            "count": lat.count,
            "cache_hits": self.cache_hits,
            "median_ms": lat.quantile(0.5) * 1e3,
            "p95_ms": lat.quantile(0.95) * 1e3,
            "max_ms": lat.max_s * 1e3,
        }

    def _clearance_result(self) -> dict:
        out: dict = {k: m.distance() for k, m in self.clearance.items()}
        for gid, m in self.fences.items():
            out[f"geofence.{gid}"] = {"margin_m": m.value, "t": m.t, "violated": m.value is not None and m.value < 0}
        for oid, (closest, cylinder) in self.objects.items():
            out[f"object.{oid}"] = closest.distance() | cylinder.result()
        return out

    def _estimation_result(self) -> dict:
        n = self.samples
        if not n or self.est_samples != n:
            return {}
        out = {"pos_rms_m": np.sqrt(self.est["pos"] / n).tolist(), "vel_rms_mps": np.sqrt(self.est["vel"] / n).tolist()}
        if self.sigma_samples == n:
            out["pos_within_3sigma"] = (self.est["pos_in"] / n).tolist()
            out["vel_within_3sigma"] = (self.est["vel_in"] / n).tolist()
            out["nees_mean"] = self.nees_sum / n
        return out

    def _storm_result(self) -> dict:
        if self.world.weather is None or not self.storm_checks:
            return {}
        span = self.storm_last_s - self.storm_first_s
        step = min(STORM_CHECK_S, max(self.world.duration_s, 1e-9) / STORM_CHECKS_MIN)
        spacing = span / (self.storm_checks - 1) if self.storm_checks > 1 else step  # per check [s]
        return {
            "min_distance_m": self.storm.value
            if self.storm.value is not None and math.isfinite(self.storm.value)
            else None,
            "t": self.storm.t,
            "time_inside_s": self.storm_inside * spacing,
        }
