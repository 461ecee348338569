"""MAVLink bridge: each simulated vehicle as a MAVLink 2 system on UDP (see docs/mavlink.md)."""

from sim.mavlink.bridge import LinkConfig, VehicleLink
from sim.mavlink.commands import Arm, Command, MissionUpload, PositionTarget, SetMode
from sim.mavlink.modes import MODES
from sim.mavlink.pacing import WallClockPacer

__all__ = [
    "MODES",
    "Arm",
    "Command",
    "LinkConfig",
    "MissionUpload",
    "PositionTarget",
    "SetMode",
    "VehicleLink",
    "WallClockPacer",
]
