"""Typed commands a ground station sent to one vehicle, as returned by ``VehicleLink.poll()``.

The link has already answered the GCS (COMMAND_ACK / MISSION_ACK) when a command is returned;
what the vehicle does with it is the runner's decision.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, slots=True)
class MissionUpload:
    """A complete, acknowledged mission upload: waypoints in flight order as
    (lat [deg], lon [deg], alt above mean sea level [m])."""

    waypoints: tuple[tuple[float, float, float], ...]


@dataclass(frozen=True, slots=True)
class SetMode:
    """Switch to the named flight mode (a name of :data:`sim.mavlink.modes.MODES`)."""

    name: str


@dataclass(frozen=True, slots=True)
class Arm:
    """Arm (``True``) or disarm (``False``) the vehicle; ``force`` when the GCS asked to
    override checks (param2 = 21196)."""

    arm: bool
    force: bool = False


@dataclass(frozen=True, slots=True)
class PositionTarget:
    """An offboard setpoint from SET_POSITION_TARGET_LOCAL_NED in the scenario's local-level NED
    frame (origin = the scenario origin = the vehicle's home).

    ``pos_ned`` [m] and ``vel_ned`` [m/s] are (3,) arrays with NaN on the axes the type_mask
    ignores, or ``None`` when all three are ignored; ``yaw`` [rad] and ``yaw_rate`` [rad/s] are
    ``None`` when ignored. Accelerations are not supported and never appear here."""

    t_boot_ms: int
    pos_ned: np.ndarray | None
    vel_ned: np.ndarray | None
    yaw: float | None
    yaw_rate: float | None


Command = MissionUpload | SetMode | Arm | PositionTarget
