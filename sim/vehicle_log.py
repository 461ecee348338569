"""What one vehicle writes to the run log each log tick.

Topics (``<v>`` = vehicle name): ``/<v>/truth/state`` (cosim.VehicleState), ``/<v>/truth/location``
(foxglove.LocationFix, Map panel), ``/<v>/ctrl/setpoint``, ``/<v>/ctrl/commands``,
``/<v>/mission/status`` (when it changes), ``/<v>/plan``; and the vehicle's pose as the transform
``ned`` -> ``<v>`` in ``/tf`` (foxglove.FrameTransforms, 3D panel). The static
``world`` (ENU, Foxglove's z-up convention) -> ``ned`` transform is written once at t = 0.
"""

from __future__ import annotations

import itertools
import json
import math
import operator
from collections.abc import Callable
from typing import Any

import numpy as np
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.GeoJSON_pb2 import GeoJSON
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from shapely.geometry import Polygon

from sim import log_rows
from sim import log_schemas as S
from sim.core.mission import Mission
from sim.core.plan import Plan, Threats
from sim.core.setpoints import FixedWingSetpoint, MultirotorSetpoint
from sim.core.state import VehicleState
from sim.core.threats import (
    Geofence,
    IntruderTrack,
    LidarScan,
    PrismObstacle,
    ScanPattern,
    SphereThreat,
    StormSnapshot,
)
from sim.energy.power_system import EnergyRecord
from sim.estimation.ins_model import three_sds
from sim.estimation.sensor_estimator import MeasurementLog, SensorEstimator, measurement_row
from sim.geodesy import GeoPoint, ned_to_geodetic
from sim.log_proto import scan_record
from sim.mcap_log import McapLog, Piece, RowBuffer
from sim.planner_records import wallclock_metadata

NED_FRAME = "ned"
WORLD_FRAME = "world"
_HALF_SQRT2 = math.sqrt(0.5)


def _seen(estimate: VehicleState) -> dict:
    """The estimate a planner saw, with its position sigma when the estimator has one."""
    seen = state_dict(estimate)
    if estimate.pos_sigma_m is not None:
        seen["pos_sigma_m"] = estimate.pos_sigma_m.tolist()
    return seen


def state_dict(s: VehicleState) -> dict:
    """A state as the ``cosim.VehicleState`` log message (plain floats and lists)."""
    return {
        "t": s.t,
        "pos_ned": s.pos_ned.tolist(),
        "vel_ned": s.vel_ned.tolist(),
        "euler": s.euler.tolist(),
        "rates_body": s.rates_body.tolist(),
        "alt_msl_m": s.alt_msl_m,
        "lat_deg": s.lat_deg,
        "lon_deg": s.lon_deg,
        "tas_mps": s.tas_mps,
        "eas_mps": s.eas_mps,
        "alpha_rad": s.alpha_rad,
        "beta_rad": s.beta_rad,
    }


def state_from_dict(d: dict) -> VehicleState:
    """A logged ``cosim.VehicleState`` message (plain dict, with ``pos_sigma_m`` in a planner
    input record) back into a VehicleState."""
    return VehicleState(
        t=float(d["t"]),
        pos_ned=np.asarray(d["pos_ned"], float),
        vel_ned=np.asarray(d["vel_ned"], float),
        euler=np.asarray(d["euler"], float),
        rates_body=np.asarray(d["rates_body"], float),
        alt_msl_m=float(d["alt_msl_m"]),
        lat_deg=float(d["lat_deg"]),
        lon_deg=float(d["lon_deg"]),
        tas_mps=float(d.get("tas_mps", 0.0)),
        eas_mps=float(d.get("eas_mps", 0.0)),
        alpha_rad=float(d.get("alpha_rad", 0.0)),
        beta_rad=float(d.get("beta_rad", 0.0)),
        pos_sigma_m=np.asarray(d["pos_sigma_m"], float) if "pos_sigma_m" in d else None,
    )


def threats_dict(t: float, th: Threats, with_scan: bool = True) -> dict:
    """Sensed threats as plain JSON, every field a planner reads (map obstacles and geofences are
    the scenario's, logged once in /world/map); ``threats_from_dict`` inverts it.
    ``with_scan=False``: without the ``lidar`` scan (a compact log has it on its own topic)."""
    lidar = th.lidar
    d = {
        "t": t,
        "intruders": [
            {
                "id": i.id,
                "t": i.t,
                "pos_ned": i.pos_ned.tolist(),
                "vel_ned": i.vel_ned.tolist(),
                "radius_m": i.radius_m,
                "pos_cov": i.pos_cov.tolist(),
                "vel_cov": i.vel_cov.tolist(),
                "cooperative": i.cooperative,
            }
            for i in th.intruders
        ],
        "spheres": [
            {
                "id": s.id,
                "t": s.t,
                "center_ned": s.center_ned.tolist(),
                "radius_m": s.radius_m,
                "vel_ned": s.vel_ned.tolist(),
                "center_cov": s.center_cov.tolist(),
            }
            for s in th.spheres
        ],
        "storms": [
            {
                "t": s.t,
                "cells": [list(c.exterior.coords) for c in s.cells],
                "velocities_ne": None if s.velocities_ne is None else np.asarray(s.velocities_ne).tolist(),
                "extents_up_m": None if s.extents_up_m is None else _extents_json(s.extents()),
            }
            for s in th.storms
        ],
        "lidar_hits": int(lidar.hit.sum()) if lidar is not None else 0,
    }
    if with_scan:
        d["lidar"] = (
            None
            if lidar is None
            else {
                "t": lidar.t,
                "origin_ned": lidar.origin_ned.tolist(),
                "directions_ned": lidar.directions_ned.tolist(),
                "ranges_m": lidar.ranges_m.tolist(),
                "hit": lidar.hit.tolist(),
                "max_range_m": lidar.max_range_m,
            }
        )
    return d


def _extents_json(ext: np.ndarray) -> list[list[float | None]]:
    """Cell extents [[base, top], ...] [m] with null where unbounded (JSON has no infinity)."""
    return [[float(b) if np.isfinite(b) else None, float(t) if np.isfinite(t) else None] for b, t in ext]


def _extents_from_json(rows: list[list[float | None]]) -> np.ndarray:
    return np.array([[-np.inf if b is None else b, np.inf if t is None else t] for b, t in rows], float).reshape(-1, 2)


def storms_from_dicts(storms: list[dict]) -> list[StormSnapshot]:
    """Logged storm snapshots (``threats_dict``'s ``storms``) back into StormSnapshots."""
    return [
        StormSnapshot(
            s["t"],
            tuple(Polygon(c) for c in s["cells"]),
            None if s.get("velocities_ne") is None else np.asarray(s["velocities_ne"], float),
            None if s.get("extents_up_m") is None else _extents_from_json(s["extents_up_m"]),
        )
        for s in storms
    ]


def threats_from_dict(
    d: dict,
    obstacles: list[PrismObstacle],
    geofences: list[Geofence],
    storms: list[StormSnapshot] | None = None,
) -> Threats:
    """A logged ``threats_dict`` message back into Threats with the scenario's map obstacles and
    geofences; ``storms``: the snapshots to use instead of the logged ones (the caller's own
    objects for an unchanged nowcast, as a planner caches a nowcast by its snapshots)."""
    a = np.asarray
    lid = d.get("lidar")
    return Threats(
        intruders=[
            IntruderTrack(
                i["id"],
                i["t"],
                a(i["pos_ned"], float),
                a(i["vel_ned"], float),
                i["radius_m"],
                a(i["pos_cov"], float),
                a(i["vel_cov"], float),
                i["cooperative"],
            )
            for i in d["intruders"]
        ],
        spheres=[
            SphereThreat(
                s["id"],
                s["t"],
                a(s["center_ned"], float),
                s["radius_m"],
                a(s["vel_ned"], float),
                a(s["center_cov"], float),
            )
            for s in d["spheres"]
        ],
        obstacles=obstacles,
        geofences=geofences,
        storms=storms_from_dicts(d["storms"]) if storms is None else storms,
        lidar=None
        if lid is None
        else LidarScan(
            lid["t"],
            a(lid["origin_ned"], float),
            a(lid["directions_ned"], float).reshape(-1, 3),
            a(lid["ranges_m"], float),
            a(lid["hit"], bool),
            lid["max_range_m"],
            None if lid.get("pattern") is None else ScanPattern(**lid["pattern"]),
            None if lid.get("rotation") is None else a(lid["rotation"], float),
            lid.get("range_resolution_m"),
        ),
    )


def mission_progress(m: Mission) -> dict:
    """The mission's mutable state (waypoints reached with their times [s], touchdown and
    completion times [s]); ``restore_progress`` sets it back."""
    return {"reached": [[k, t] for k, t in m.reached], "landed_t": m.landed_t, "completed_t": m.completed_t}


def mission_setup(m: Mission) -> dict:
    """What a mission is made of (waypoints NED [m], cruise speed [m/s], acceptance radius [m],
    first leg's start NED [m] or None, hover times [s] by waypoint index, landing);
    ``mission_from_setup`` builds it again."""
    return {
        "waypoints": np.asarray(m.waypoints, float).tolist(),
        "cruise_speed": m.cruise_speed,
        "acceptance_radius": m.acceptance_radius,
        "start": None if m.start is None else np.asarray(m.start, float).tolist(),
        "hold_s": [[k, s] for k, s in m.hold_s.items()],
        "land": m.land,
    }


def mission_from_setup(d: dict) -> Mission:
    """A logged :func:`mission_setup` as a new Mission (no progress)."""
    return Mission(
        np.asarray(d["waypoints"], float).reshape(-1, 3),
        float(d["cruise_speed"]),
        float(d["acceptance_radius"]),
        start=None if d["start"] is None else np.asarray(d["start"], float),
        hold_s={int(k): float(s) for k, s in d["hold_s"]},
        land=bool(d["land"]),
    )


def restore_progress(m: Mission, d: dict) -> None:
    m.reached = [(int(k), float(t)) for k, t in d["reached"]]
    m.landed_t, m.completed_t = d["landed_t"], d["completed_t"]


def setpoint_record(sp: FixedWingSetpoint | MultirotorSetpoint, follower: Any, origin: GeoPoint) -> dict:
    """The ``/<v>/ctrl/setpoint`` record of a setpoint with the follower's leg, cross-track [m]
    and turning flag; NaN: not controlled (null in JSON, None when read back)."""
    common = {"leg": follower.leg, "cross_track_m": follower.cross_track_m, "turning": follower.turning}
    if isinstance(sp, MultirotorSetpoint):
        d = float(sp.pos_ned[2])
        return {
            "pos_ned": [float(x) for x in sp.pos_ned],
            "vel_ned": [float(x) for x in sp.vel_ned],
            "yaw_rad": float(sp.yaw_rad),
            "altitude_m": origin.alt_m - d,
            **common,
        }
    return {"roll_rad": sp.roll_rad, "altitude_m": sp.altitude_m, "tas_mps": sp.tas_mps, **common}


def write_static_frames(log: McapLog) -> None:
    """``world`` (ENU) -> ``ned``: NED axes expressed in ENU, a 180 deg turn about (1, 1, 0)."""
    tf = FrameTransform(parent_frame_id=WORLD_FRAME, child_frame_id=NED_FRAME)
    tf.timestamp.FromNanoseconds(log.epoch_ns)
    tf.rotation.x, tf.rotation.y, tf.rotation.z, tf.rotation.w = _HALF_SQRT2, _HALF_SQRT2, 0.0, 0.0
    log.write_proto("/tf_static", 0.0, FrameTransforms(transforms=[tf]))


_STATE_META = {"frame": "local-level NED from the scenario origin", "units": "SI, rad"}
_ENERGY_SCALARS = operator.attrgetter(*(name for name, width in log_rows.ENERGY if width != log_rows.MAP))
_ENERGY_META = {"units": "W, Wh, state of charge 0..1"}
_SENSORS_META = {"units": "SI, rad"}
_SIGMA_META = {"frame": "NED; attitude error in body axes", "units": "SI, rad"}


def state_row(s: VehicleState) -> list[float]:
    """A state as a ``truth``/``estimate`` row (:data:`sim.log_rows.STATE`)."""
    return [
        s.t,
        *s.pos_ned.tolist(),
        *s.vel_ned.tolist(),
        *s.euler.tolist(),
        *s.rates_body.tolist(),
        s.alt_msl_m,
        s.lat_deg,
        s.lon_deg,
        s.tas_mps,
        s.eas_mps,
        s.alpha_rad,
        s.beta_rad,
    ]


_SETPOINT_VALUES = {  # setpoint layout: its record's values after ``t``
    name: log_rows.record_values(log_rows.LAYOUTS[name].columns[1:]) for name in log_rows.SETPOINT_LAYOUTS.values()
}
# a tick's control: setpoint record, its JSON schema, commands sent to the plant, controller debug
ControlRecord = tuple[dict[str, Any], dict[str, Any], dict[str, float], dict[str, float]]


def _sensors_row(tick: tuple[float, MeasurementLog]) -> list[float]:
    """A ``sensors`` row: the log tick's time [s] and its measurements."""
    t, measurements = tick
    return [t, *measurement_row(measurements)]


def _setpoint_row(tick: tuple[float, Callable[[dict], list[float]], dict]) -> list[float]:
    """A setpoint row: the log tick's time [s] and the setpoint record's columns."""
    t, values, setpoint = tick
    return [t, *values(setpoint)]


def _commands_row(tick: tuple[float, dict[str, float], dict[str, float]]) -> list[float]:
    """A ``commands`` row: the log tick's time [s], the commands' and the debug values."""
    t, commands, debug = tick
    return [t, *commands.values(), *debug.values()]


class VehicleLogWriter:
    """Formats and writes one vehicle's messages; topic names are built once. In a compact log
    the per-tick topics are rows (:mod:`sim.log_rows`) that the writer process encodes; a JSON
    log writes each message as a dict."""

    def __init__(self, log: McapLog, name: str):
        self.log = log
        self.name = name
        p = f"/{name}"
        self.t_state, self.t_loc = f"{p}/truth/state", f"{p}/truth/location"
        self.t_sp, self.t_cmd, self.t_mission = f"{p}/ctrl/setpoint", f"{p}/ctrl/commands", f"{p}/mission/status"
        self.t_plan, self.t_latency, self.t_input = f"{p}/plan", f"{p}/plan/latency", f"{p}/plan/input"
        self.t_observation = f"{p}/plan/observation"
        self.t_est, self.t_threats = f"{p}/est/state", f"{p}/threats"
        self.t_sensors, self.t_sigma = f"{p}/sensors", f"{p}/est/sigma3"
        self.t_tracking = f"{p}/truth/tracking"
        self.t_energy = f"{p}/energy"
        self.t_lidar = f"{p}/threats/lidar"
        # row specs by the parts' varying static values: the setpoint layout and the map keys,
        # then the sensors' record counts (these change from tick to tick)
        self._specs: dict[tuple, dict[tuple | None, tuple]] = {}
        self._last_keys: tuple = ()
        self._by_counts: dict[tuple | None, tuple] = {}
        self._buffer = RowBuffer(log) if log.compact else None
        sp: tuple[tuple[str, ...], tuple[dict[str, str], ...]] = ((self.t_sp,), ({},))
        self._part_topics: dict[str, tuple[tuple[str, ...], tuple[dict[str, str], ...]]] = {  # per layout
            "truth": ((self.t_state, self.t_loc, "/tf"), (_STATE_META, {}, {})),
            "tracking": ((self.t_tracking,), ({},)),
            "estimate": ((self.t_est,), (_STATE_META,)),
            "sensors": ((self.t_sensors,), (_SENSORS_META,)),
            "sigma": ((self.t_sigma,), (_SIGMA_META,)),
            "fixed_wing_setpoint": sp,
            "multirotor_setpoint": sp,
            "commands": ((self.t_cmd,), ({},)),
            "energy": ((self.t_energy,), (_ENERGY_META,)),
        }

    def tick(
        self,
        t: float,
        truth: VehicleState,
        track: tuple[float, int],
        estimate: VehicleState,
        estimator: SensorEstimator | None,
        control: ControlRecord,
        energy: EnergyRecord | None,
        mission: tuple[int, int, bool] | None = None,
    ) -> dict[str, Any] | None:
        """One log tick's per-tick topics: the true state (``cosim.VehicleState``,
        ``foxglove.LocationFix``, the ``ned`` -> vehicle transform on ``/tf``), ``track`` (true
        cross-track error [m] to the leg being followed, that leg: what the metrics judge), the
        estimate (what controllers and planners saw); with a :class:`SensorEstimator`, the
        measurements delivered since the last tick and the estimate's 3-sigma bounds and biases;
        ``control`` (the setpoint record of :func:`setpoint_record`, its JSON schema, the
        commands sent to the plant and the controller's debug values: none of the three dicts
        may change later), the electrical bus at ``t`` [s] (its record's own ``t`` ends the
        control step) and ``mission`` (next waypoint, waypoints, complete) when it changed.
        Returns the 3-sigma bounds as logged (``pos``, ``vel``, ...: sequences of floats), None
        without a sensor estimator. In a compact log the topics are one row (:mod:`sim.log_rows`)
        whose values are taken when its block is handed over (states, measurements and the
        control dicts are not changed later; the bus record and the covariance are read now)."""
        if not self.log.compact:
            sigma3 = self._tick_json(t, truth, track, estimate, estimator, control, energy)
            if mission is not None:
                self.mission(t, *mission)
            return sigma3
        if mission is not None:  # before the row's channels (the order they had before rows)
            self.mission(t, *mission)
        setpoint, schema, commands, debug = control
        layout = log_rows.SETPOINT_LAYOUTS[schema["title"]]
        pieces: list[Piece] = [[t, *track], (state_row, truth), (state_row, estimate)]
        counts: tuple[tuple[str, int], ...] | None = None
        sigma3 = None
        if estimator is not None:
            sensors = estimator.take_measurements()
            counts = tuple([(name, len(items)) for name, items in sensors.items()])
            cov = estimator.covariance_row()
            pieces += ((_sensors_row, (t, sensors)), [t, *cov])
            sd = three_sds(cov[0:6])
            sigma3 = {"pos": sd[0:3], "vel": sd[3:6]}
        pieces += (
            (_setpoint_row, (t, _SETPOINT_VALUES[layout], setpoint)),
            (_commands_row, (t, commands, debug)),
        )
        cum = None
        if energy is not None:
            cum = energy.cumulative_wh  # the record changes in place: its values are taken now
            pieces.append([t, *_ENERGY_SCALARS(energy), *cum.values()])
        keys = (layout, tuple(commands), tuple(debug), None if cum is None else tuple(cum))
        if keys != self._last_keys:  # mostly equal: compared by the identity of their strings
            self._last_keys, self._by_counts = keys, self._specs.setdefault(keys, {})
        spec = self._by_counts.get(counts)
        if spec is None:
            spec = self._by_counts[counts] = self._row_spec(keys, counts)
        assert self._buffer is not None, "rows are written to compact logs only"
        self._buffer.add(spec, pieces)
        return sigma3

    def _row_spec(self, keys: tuple, counts: tuple | None) -> tuple:
        """The spec of a row of :meth:`tick` with the parts' varying static values (``keys``:
        setpoint layout, map keys; the sensors' record counts), registering the parts'
        channels at the first."""
        layout, properties, debug, cumulative = keys
        parts: list[tuple[str, tuple]] = [("tracking", ()), ("truth", (("frame", self.name),)), ("estimate", ())]
        if counts is not None:
            parts += (("sensors", (("counts", counts),)), ("sigma", ()))
        parts += ((layout, ()), ("commands", (("properties", properties), ("debug", debug))))
        if cumulative is not None:
            parts.append(("energy", (("cumulative_wh", cumulative),)))
        topics = self._part_topics
        return self.log.row_spec(tuple((name, topics[name][0], static, topics[name][1]) for name, static in parts))

    def _tick_json(
        self,
        t: float,
        truth: VehicleState,
        track: tuple[float, int],
        estimate: VehicleState,
        estimator: SensorEstimator | None,
        control: ControlRecord,
        energy: EnergyRecord | None,
    ) -> dict[str, Any] | None:
        """:meth:`tick` in a JSON log: one message per topic, each a dict."""
        log = self.log
        cross_track_m, leg = track
        log.write_json(self.t_tracking, t, {"t": t, "cross_track_m": cross_track_m, "leg": leg}, S.TRACKING)
        ns = log.epoch_ns + round(truth.t * 1e9)
        log.write_json(self.t_state, truth.t, state_dict(truth), S.VEHICLE_STATE, _STATE_META)
        row = state_row(truth)
        log.write_proto(self.t_loc, truth.t, log_rows.location_fix(row, ns, self.name))
        log.write_proto("/tf", truth.t, log_rows.ned_transforms(row, ns, self.name))
        log.write_json(self.t_est, estimate.t, state_dict(estimate), S.VEHICLE_STATE, _STATE_META)
        sigma3 = None
        if estimator is not None:
            sigma3 = estimator.three_sigma()
            log.write_json(self.t_sensors, t, {"t": t, **estimator.measurements()}, S.SENSORS, _SENSORS_META)
            sigma = {"t": t, **sigma3, "bias": estimator.biases()}
            log.write_json(self.t_sigma, t, sigma, S.ESTIMATE_SIGMA, _SIGMA_META)
        setpoint, schema, commands, debug = control
        log.write_json(self.t_sp, t, {"t": t, **setpoint}, schema)
        log.write_json(self.t_cmd, t, {"t": t, "properties": commands, "debug": debug}, S.COMMANDS)
        if energy is not None:
            log.write_json(self.t_energy, t, energy.as_dict(), S.ENERGY, _ENERGY_META)
        return sigma3

    def mission(self, t: float, next_waypoint: int, waypoints: int, complete: bool) -> None:
        self.log.write_json(
            self.t_mission,
            t,
            {"t": t, "next_waypoint": next_waypoint, "waypoints": waypoints, "complete": complete},
            S.MISSION_STATUS,
        )

    def threats(self, t: float, threats: Threats) -> None:
        """The threats as sensed when a plan was made (what the planner saw); in a compact log
        the LiDAR scan goes to ``/<v>/threats/lidar`` (cosim.LidarScan) at the same log time."""
        compact = self.log.compact and threats.lidar is not None
        frame = {"frame": "local-level NED from the scenario origin"}
        self.log.write_json(self.t_threats, t, threats_dict(t, threats, with_scan=not compact), S.THREATS, frame)
        if compact and threats.lidar is not None:
            self.log.write_record(self.t_lidar, t, scan_record(threats.lidar), S.LIDAR_SCAN, frame)

    def plan_input(
        self,
        t: float,
        planner: str,
        estimate: VehicleState,
        mission: Mission,
        new_plan: bool,
        fresh: bool,
        mode_setup: dict | None = None,
    ) -> None:
        """Per planner call: the planner's name, the estimate and mission progress it saw (the
        threats go to ``/<v>/threats``, one message per call too) and whether it made a new plan;
        ``fresh``: the planner was built since the previous call (at the start, a ground-station
        mode change or mission upload, a repeated mission): the record then holds the mission it
        was built for (``mission_setup``) and, for a ground-station mode planner, what it was
        built from (``mode_setup``)."""
        rec = {
            "t": t,
            "planner": planner,
            "estimate": _seen(estimate),
            "mission": mission_progress(mission),
            "new_plan": new_plan,
        }
        if fresh:
            rec["mission_setup"] = mission_setup(mission)
            if mode_setup is not None:
                rec["mode_setup"] = mode_setup
        self.log.write_json(
            self.t_input,
            t,
            rec,
            S.PLAN_INPUT,
            {"frame": "local-level NED from the scenario origin"},
        )

    def plan_observation(self, t: float, estimate: VehicleState) -> None:
        """An estimate an observing planner sampled between its calls (sim.core.plan)."""
        self.log.write_json(
            self.t_observation,
            t,
            {"t": t, "estimate": _seen(estimate)},
            S.PLAN_OBSERVATION,
            {"frame": "local-level NED from the scenario origin"},
        )

    def plan(self, plan: Plan) -> None:
        """A new plan, once, at its creation time."""
        t = plan.t
        self.log.write_json(
            self.t_plan,
            t,
            {
                "t": t,
                "planner": plan.planner,
                "status": plan.status.value,
                "positions": plan.positions.tolist(),
                "times": plan.times.tolist(),
                "labels": plan.labels.tolist(),
                "diagnostics": plan.diagnostics,
                **({} if plan.turn_rates is None else {"turn_rates": plan.turn_rates.tolist()}),
                **({} if plan.airspeeds is None else {"airspeeds": plan.airspeeds.tolist()}),
            },
            S.PLAN,
            {"frame": "local-level NED from the scenario origin", **wallclock_metadata(plan.planner, "")},
        )

    def latency(self, t: float, seconds: float) -> None:
        """Wall-clock time [s] of a planner call that made a new plan."""
        self.log.write_json(
            self.t_latency,
            t,
            {"t": t, "seconds": seconds},
            S.WALL_TIMING,
            {"wallclock": "true", "wallclock_fields": "seconds"},
        )


def _prism_lines(footprint, d_top: float, d_bottom: float) -> list[tuple[float, float, float]]:
    """LINE_LIST segments outlining a prism in NED: top and bottom rings and the verticals."""
    polys = getattr(footprint, "geoms", [footprint])
    pts: list[tuple[float, float, float]] = []
    for poly in polys:
        ring = list(poly.exterior.coords)
        for (n0, e0), (n1, e1) in itertools.pairwise(ring):
            pts += [
                (n0, e0, d_top),
                (n1, e1, d_top),
                (n0, e0, d_bottom),
                (n1, e1, d_bottom),
                (n0, e0, d_top),
                (n0, e0, d_bottom),
            ]
    return pts


def write_map(log: McapLog, obstacles: list, fences: list, origin) -> None:
    """Obstacles and geofences once at t = 0: ``/world/map`` (foxglove.GeoJSON, Map panel) and
    ``/world/obstacles`` (foxglove.SceneUpdate outlines in frame ``ned``, 3D panel)."""
    if not obstacles and not fences:
        return
    features = []
    scene = SceneUpdate()
    for item, colour in [(o, (0.9, 0.3, 0.2)) for o in obstacles] + [(g, (0.2, 0.6, 0.9)) for g in fences]:
        shape = item.footprint if hasattr(item, "footprint") else item.area
        for poly in getattr(shape, "geoms", [shape]):
            lat, lon, _ = ned_to_geodetic([(n, e, 0.0) for n, e in poly.exterior.coords], origin)
            features.append(
                {
                    "type": "Feature",
                    "properties": {
                        "id": item.id,
                        "kind": "obstacle" if hasattr(item, "footprint") else "geofence",
                        "up_min_m": item.up_min_m,
                        "up_max_m": item.up_max_m,
                        "keep_in": getattr(item, "keep_in", False),  # obstacles: keep out
                    },
                    "geometry": {
                        "type": "Polygon",
                        "coordinates": [list(zip(lon.tolist(), lat.tolist(), strict=False))],
                    },
                }
            )
        ent = scene.entities.add(frame_id=NED_FRAME, id=item.id)
        ent.timestamp.FromNanoseconds(log.epoch_ns)
        line = ent.lines.add(type=LinePrimitive.LINE_LIST, thickness=2.0, scale_invariant=True)
        line.pose.orientation.w = 1.0
        line.color.r, line.color.g, line.color.b, line.color.a = (*colour, 1.0)
        for n, e, d in _prism_lines(shape, -item.up_max_m, -max(item.up_min_m, -1e4)):
            p = line.points.add()
            p.x, p.y, p.z = n, e, d
    log.write_proto("/world/map", 0.0, GeoJSON(geojson=json.dumps({"type": "FeatureCollection", "features": features})))
    log.write_proto("/world/obstacles", 0.0, scene)
