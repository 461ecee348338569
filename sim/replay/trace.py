"""A vehicle's time series as metrics need them, built live during a run or from its log.

The same :class:`VehicleTrace` chunks come out of both paths (:class:`TraceRecorder`, fed live or
from the log by :mod:`sim.replay.log_stream`), so metrics computed live and recomputed
from the MCAP are the same numbers (JSON floats round-trip exactly).
Units: NED [m], altitude MSL [m], speeds [m/s], angles [rad], times sim [s].
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace

import numpy as np

from sim.core.state import VehicleState
from sim.mcap_log import logged_time

# truth-state fields and the setpoint fields every follower logs; tas_mps only for fixed wing
_STATE = ("t", "pos_ned", "vel_ned", "alt_msl_m", "tas_mps", "euler")
_SETPOINT = ("altitude_m", "cross_track_m", "turning")
_SETPOINT_OPTIONAL = ("tas_mps",)
CHUNK = 1024  # log ticks per chunk that metrics fold in at once (live and replay cut the same)


@dataclass
class VehicleTrace:
    name: str
    kind: str  # "fixed_wing" | "multirotor"
    t: np.ndarray
    pos_ned: np.ndarray  # (N, 3)
    alt_msl_m: np.ndarray
    tas_mps: np.ndarray
    euler: np.ndarray  # (N, 3)
    setpoint: dict[str, np.ndarray]  # altitude_m, cross_track_m, turning (+ tas_mps) (N,)
    plan_latency_s: np.ndarray
    waypoints_total: int
    waypoint_times: list[float]  # sim time each waypoint was reached
    complete_t: float | None = None  # sim time the mission completed
    commands: dict[str, np.ndarray] = field(default_factory=dict)  # JSBSim property -> values
    est_pos_ned: np.ndarray | None = None  # (N, 3) estimate at the same ticks [m]
    est_vel_ned: np.ndarray | None = None  # (N, 3) [m/s]
    sigma3_pos: np.ndarray | None = None  # (N, 3) 3-sigma bounds [m] (None: perfect estimator)
    sigma3_vel: np.ndarray | None = None  # (N, 3) [m/s]
    truth_vel_ned: np.ndarray | None = None  # (N, 3) true velocity [m/s]
    truth_cross_track_m: np.ndarray | None = None  # (N,) true cross-track to the followed leg [m]
    plan_cache_hits: int = 0  # planner calls that kept the previous plan

    def chunks(self, size: int) -> Iterator[VehicleTrace]:
        """The trace cut into pieces of ``size`` samples (at least one piece); the per-run values
        (latencies, waypoint times, cache hits) go with the first."""
        for start in range(0, max(len(self.t), 1), size):
            sl = slice(start, start + size)

            def cut(a: np.ndarray | None, sl: slice = sl) -> np.ndarray | None:
                return None if a is None else a[sl]

            first = start == 0
            yield replace(
                self,
                t=self.t[sl],
                pos_ned=self.pos_ned[sl],
                alt_msl_m=self.alt_msl_m[sl],
                tas_mps=self.tas_mps[sl],
                euler=self.euler[sl],
                setpoint={k: v[sl] for k, v in self.setpoint.items()},
                plan_latency_s=self.plan_latency_s if first else np.zeros(0),
                waypoint_times=self.waypoint_times if first else [],
                commands={k: v[sl] for k, v in self.commands.items()},
                est_pos_ned=cut(self.est_pos_ned),
                est_vel_ned=cut(self.est_vel_ned),
                sigma3_pos=cut(self.sigma3_pos),
                sigma3_vel=cut(self.sigma3_vel),
                truth_vel_ned=cut(self.truth_vel_ned),
                truth_cross_track_m=cut(self.truth_cross_track_m),
                plan_cache_hits=self.plan_cache_hits if first else 0,
            )

    def true_cross_track(self) -> np.ndarray:
        """(N,) true cross-track to the followed leg [m]."""
        if self.truth_cross_track_m is None:
            raise ValueError(f"{self.name}: the trace has no true cross-track")
        return self.truth_cross_track_m

    @property
    def mission_complete(self) -> bool:
        return self.complete_t is not None


_VECTORS = ("pos_ned", "vel_ned", "euler")


def _array(key: str, values: list) -> np.ndarray:
    a = np.asarray(values, dtype=float)
    return a.reshape(-1, 3) if key in _VECTORS else a


@dataclass
class TraceRecorder:
    """Collects the values a vehicle logs, as they are logged (the live side), and hands them to
    ``sink`` in chunks of ``chunk`` log ticks (then forgets them); :meth:`flush` hands over the
    rest at the run's end."""

    name: str
    kind: str
    waypoints_total: int
    sink: Callable[[VehicleTrace], None] | None = None
    chunk: int = CHUNK
    _state: dict[str, list] = field(default_factory=lambda: {k: [] for k in _STATE})
    _setpoint: dict[str, list] = field(default_factory=lambda: {k: [] for k in _SETPOINT})
    _latency: list[float] = field(default_factory=list)
    _cache_hits: int = 0
    _reached: list[float] = field(default_factory=list)
    _complete_t: float | None = None
    _commands: list[dict[str, float]] = field(default_factory=list)
    _cross: list[float] = field(default_factory=list)
    _est: dict[str, list] = field(default_factory=lambda: {"pos_ned": [], "vel_ned": []})
    _sigma: dict[str, list] = field(default_factory=lambda: {"pos": [], "vel": []})

    def estimate(self, est: VehicleState, sigma3: dict | None) -> None:
        """The estimate logged at the tick of the last :meth:`state` (completes the tick)."""
        for k, values in self._est.items():
            values.append(getattr(est, k))
        if sigma3 is not None:
            for k in self._sigma:
                self._sigma[k].append(sigma3[k])
        if len(self._cross) >= self.chunk:
            self.flush()

    def state(self, state: VehicleState, setpoint: dict, commands: dict[str, float], cross_track_m: float) -> None:
        """The true state logged at a tick (its arrays are kept: the caller must not change them)."""
        self._cross.append(cross_track_m)
        for k, values in self._state.items():
            values.append(getattr(state, k))
        for k in _SETPOINT + _SETPOINT_OPTIONAL:
            if k in setpoint:
                self._setpoint.setdefault(k, []).append(setpoint[k])
        self._commands.append(commands)

    def latency(self, seconds: float) -> None:
        self._latency.append(seconds)

    def cache_hit(self) -> None:
        self._cache_hits += 1

    def reached(self, t: float) -> None:
        """A waypoint reached at ``t`` [s]: kept as its ``/log`` event's time reads back."""
        self._reached.append(logged_time(t))

    def complete(self, t: float) -> None:
        """The mission completed at ``t`` [s]: kept as its ``/log`` event's time reads back."""
        self._complete_t = logged_time(t)

    def flush(self) -> None:
        """Hand the collected ticks to the sink and start a new chunk."""
        if self.sink is not None:
            self.sink(self.trace())
        for lists in (self._state, self._setpoint, self._est, self._sigma):
            for v in lists.values():
                v.clear()
        for lst in (self._latency, self._reached, self._commands, self._cross):
            lst.clear()
        self._cache_hits = 0

    def trace(self) -> VehicleTrace:
        """The series of the current chunk; vectors are (N, 3) also when nothing was logged."""
        s = {k: _array(k, v) for k, v in self._state.items()}
        return VehicleTrace(
            self.name,
            self.kind,
            s["t"],
            s["pos_ned"],
            s["alt_msl_m"],
            s["tas_mps"],
            s["euler"],
            {k: np.asarray(v, dtype=float) for k, v in self._setpoint.items()},
            np.asarray(self._latency, dtype=float),
            self.waypoints_total,
            list(self._reached),
            self._complete_t,
            self._command_arrays(),
            est_pos_ned=_array("pos_ned", self._est["pos_ned"]),
            est_vel_ned=_array("vel_ned", self._est["vel_ned"]),
            sigma3_pos=self._sigma_array("pos"),
            sigma3_vel=self._sigma_array("vel"),
            truth_vel_ned=s["vel_ned"],
            truth_cross_track_m=np.asarray(self._cross, dtype=float),
            plan_cache_hits=self._cache_hits,
        )

    def _sigma_array(self, key: str) -> np.ndarray | None:
        return np.asarray(self._sigma[key], dtype=float) if self._sigma[key] else None

    def _command_arrays(self) -> dict[str, np.ndarray]:
        props = self._commands[-1].keys() if self._commands else ()
        return {p: np.array([c.get(p, np.nan) for c in self._commands]) for p in props}
