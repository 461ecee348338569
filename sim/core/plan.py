"""The planner interface shared by the follow-mission planner, the avoiders and the MPTP.

A planner is called at its own rate with the vehicle's *estimate* (never truth) and the threats
as sensed, and returns a :class:`Plan`: a time-stamped reference trajectory in the scenario's
local-level NED frame [m], times in sim seconds, plus a status and diagnostics. Planners may keep
state between calls. Guidance follows the newest plan; the runner logs every plan. A planner
that also needs the estimate between its calls (an :class:`ObservingPlanner`) gets it at its own
``observe_hz``, once it has been called; the runner logs those estimates too, so a re-run feeds
them again.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from typing import Protocol, runtime_checkable

import numpy as np

from sim.core.state import VehicleState
from sim.core.threats import Geofence, IntruderTrack, LidarScan, PrismObstacle, SphereThreat, StormSnapshot


class PlanStatus(str, Enum):
    OK = "ok"
    DEGRADED = "degraded"
    NO_SOLUTION = "no_solution"


@dataclass(slots=True)
class Plan:
    """Reference trajectory: ``positions`` (N, 3) NED [m], ``times`` (N,) sim time [s] at which
    each vertex is due, optional ``velocities`` (N, 3) NED [m/s], and per-vertex ``labels``
    (mission waypoint index, or -1 for a vertex the planner added). ``speed`` [m/s]: a speed the
    planner commands along the plan below the mission's cruise speed (the rules' overtake speed
    change, 6.202), honoured by the multirotor follower; None = the cruise speed.
    ``turn_rates`` (N,) [rad/s]: the rate of the air-relative course (+ = right) the planner's
    aircraft model flies on the leg from each vertex to the next (the last entry unused), fed
    forward as bank by the fixed-wing follower; None = straight legs between corners.
    ``airspeeds`` (N,) [m/s]: the true airspeed the planner commands on the leg from each vertex
    to the next (the last entry unused), taken by the fixed-wing follower as its airspeed demand
    (the flight controller bounds it to the airframe's envelope), e.g. an MPTP holding orbit
    flown at V_cor; None = the mission's cruise airspeed on every leg."""

    t: float
    positions: np.ndarray
    times: np.ndarray
    labels: np.ndarray
    status: PlanStatus = PlanStatus.OK
    velocities: np.ndarray | None = None
    planner: str = ""
    diagnostics: dict[str, float | int | str] = field(default_factory=dict)
    speed: float | None = None
    turn_rates: np.ndarray | None = None
    airspeeds: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = len(self.positions)
        if self.positions.shape != (n, 3) or self.times.shape != (n,) or self.labels.shape != (n,):
            raise ValueError("plan arrays must be positions (N,3), times (N,), labels (N,)")
        if self.turn_rates is not None and self.turn_rates.shape != (n,):
            raise ValueError(f"plan turn_rates must be (N,) = ({n},), got {self.turn_rates.shape}")
        if self.airspeeds is not None and (self.airspeeds.shape != (n,) or not np.all(self.airspeeds > 0)):
            raise ValueError(f"plan airspeeds must be (N,) = ({n},) and > 0 m/s, got {self.airspeeds!r}")


@dataclass(slots=True)
class Threats:
    """What the vehicle knows of the world around it at one instant (types: sim.core.threats):
    tracked intruders, spherical threats, map obstacles, geofences, the storm nowcast (snapshots
    in time order) and the latest LiDAR scan."""

    intruders: list[IntruderTrack] = field(default_factory=list)
    spheres: list[SphereThreat] = field(default_factory=list)
    obstacles: list[PrismObstacle] = field(default_factory=list)
    geofences: list[Geofence] = field(default_factory=list)
    storms: list[StormSnapshot] = field(default_factory=list)
    lidar: LidarScan | None = None


class Planner(Protocol):
    name: str

    def plan(self, estimate: VehicleState, threats: Threats, t: float) -> Plan: ...


@runtime_checkable
class ObservingPlanner(Planner, Protocol):
    """A planner that also samples the estimate between its calls, at ``observe_hz`` [Hz] (for
    instance to average a noisy airspeed over more samples than its calls give)."""

    observe_hz: float

    def observe(self, estimate: VehicleState, t: float) -> None: ...
