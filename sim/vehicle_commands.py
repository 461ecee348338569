"""Ground-station commands (MAVLink) acting on one vehicle: mission upload, mode changes
(AUTO: the mission; HOLD: hover in place; GUIDED: fly to position targets), arming requests.
Every command is logged as an event. Positions: local-level NED from the scenario origin [m].

A path commanded to a landed multirotor (an uploaded mission, a GUIDED position target) starts
above it, at the height of the path's first point: the multirotor takes off when its setpoint is
above it, and a first leg from where it stands keeps the setpoint on the ground while the
vehicle is not moving along it (a deadlock)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from sim.core.mission import Mission
from sim.geodesy import geodetic_to_ned
from sim.mavlink.commands import Arm, MissionUpload, PositionTarget, SetMode
from sim.position_planners import GotoPlanner, HoldPositionPlanner

if TYPE_CHECKING:
    from sim.vehicle import Vehicle


def apply_command(v: Vehicle, cmd: object, t: float) -> bool:
    """Act on a ground-station command at sim time ``t`` [s]; True when the mission changed."""
    multirotor = v.airframe.kind == "multirotor"
    if isinstance(cmd, MissionUpload):
        lat, lon, alt = np.asarray(cmd.waypoints, float).T
        wps = geodetic_to_ned(lat, lon, alt, v.origin)
        m = v.mission
        v.mission = Mission(wps, m.cruise_speed, m.acceptance_radius, start=_departure(v, wps[0, 2]), land=m.land)
        v.planner = v.make_mission_planner()
        if multirotor:
            v.follower.set_waypoint_attributes({}, {})
        v.recorder.waypoints_total = len(wps)
        v.mode = "AUTO"
        v.event(t, f"mission uploaded: {len(wps)} waypoints, mode AUTO")
        v.plan_now(t)
        return True
    if isinstance(cmd, SetMode):
        if cmd.name == "AUTO":
            v.planner = v.make_mission_planner()
        elif cmd.name in ("HOLD", "GUIDED") and multirotor:
            v.planner = HoldPositionPlanner(v.estimate.pos_ned)
        else:
            v.event(t, f"mode {cmd.name} refused: not available for a {v.airframe.kind}")
            return False
        v.mode = cmd.name
        v.event(t, f"mode {cmd.name}")
        v.plan_now(t)
        return False
    if isinstance(cmd, PositionTarget):
        if v.mode != "GUIDED" or not multirotor or cmd.pos_ned is None or np.isnan(cmd.pos_ned).any():
            v.event(t, "position target ignored (needs GUIDED mode, a multirotor and a full position)")
            return False
        v.planner = GotoPlanner(_departure(v, float(cmd.pos_ned[2])), cmd.pos_ned, v.mission.cruise_speed)
        v.event(t, "position target: " + ", ".join(f"{x:.1f}" for x in cmd.pos_ned) + " m NED")
        v.plan_now(t)
        return False
    if isinstance(cmd, Arm):
        # arming follows from the mission (take-off demand); disarming in flight is refused
        v.event(
            t,
            f"{'arm' if cmd.arm else 'disarm'} request noted; motors follow the flight controller (armed: {v.armed})",
        )
        return False
    raise TypeError(f"unknown command {cmd!r}")


def _departure(v: Vehicle, first_down: float) -> np.ndarray:
    """Where a commanded path starts (NED [m]): the estimate, lifted to ``first_down`` (the path's
    first point's down coordinate) for a landed multirotor, so that it takes off straight up."""
    start = np.array(v.estimate.pos_ned, float)
    if v.airframe.kind == "multirotor" and v._multirotor().landed:
        start[2] = min(start[2], first_down)
    return start
