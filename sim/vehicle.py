"""One simulated vehicle: JSBSim plant, estimator, planner, plan follower, flight controller.

Data flow per tick (see architecture.md): the estimator produces the estimate; the planner
(at its rate) turns estimate + sensed threats into a Plan; the follower turns the plan into a
setpoint; the controller turns setpoint + estimate into JSBSim property commands. Only the
logger reads the plant's truth.
"""

from __future__ import annotations

import math
import time

import numpy as np

from aircraft.registry import get_airframe
from avoidance.follow_mission import FollowMissionPlanner
from avoidance.planner import Plan, Threats
from guidance.fixed_wing_follower import FixedWingPlanFollower
from guidance.l1 import L1Guidance
from guidance.mission import Mission
from sim import scenario as sc
from sim.estimator import PerfectEstimator
from sim.frames import GeoPoint, ned_to_geodetic
from sim.jsbsim_plant import InitialConditions, JSBSimPlant
from sim.mcap_log import McapLog
from sim.replay.trace import TraceRecorder
from sim.scheduler import LockstepScheduler, Stage
from sim.vehicle_log import VehicleLogWriter, setpoint_dict


class SimulationDiverged(RuntimeError):
    """The plant's state went non-finite."""


def _ned(north: float, east: float, altitude: float, origin: GeoPoint) -> np.ndarray:
    return np.array([north, east, origin.alt_m - altitude])


class Vehicle:
    def __init__(self, cfg: sc.Vehicle, origin: GeoPoint, log: McapLog):
        self.name = cfg.name
        self.cfg = cfg
        self.airframe = get_airframe(cfg.aircraft)
        if self.airframe.kind != "fixed_wing":
            raise NotImplementedError(f"vehicle {cfg.name}: {self.airframe.kind} vehicles are not supported yet")
        self.log = log
        self.logw = VehicleLogWriter(log, cfg.name)
        af = self.airframe
        self.plant = JSBSimPlant(af.jsbsim_model, 1.0 / af.plant_hz, origin, af.folder)
        ini = cfg.initial
        lat, lon, alt = ned_to_geodetic(_ned(ini.north, ini.east, ini.altitude, origin), origin)
        self.plant.initialise(InitialConditions(
            position=GeoPoint(float(lat), float(lon), float(alt)), tas_mps=ini.airspeed,
            heading_rad=ini.heading, on_ground=ini.on_ground))
        if ini.trim:
            self.plant.trim()
        m = cfg.mission
        self.mission = Mission(
            waypoints=np.array([_ned(w.north, w.east, w.altitude, origin) for w in m.waypoints]),
            cruise_speed=m.cruise_speed, acceptance_radius=m.acceptance_radius,
            start=_ned(ini.north, ini.east, ini.altitude, origin))
        self.estimator = PerfectEstimator(self.plant)
        self.planner = FollowMissionPlanner(self.mission)
        self.controller = af.make_controller(cfg.gains)
        self.follower = FixedWingPlanFollower(L1Guidance.for_airframe(self.controller), m.cruise_speed,
                                              m.acceptance_radius, origin.alt_m)
        self.recorder = TraceRecorder(cfg.name, len(self.mission.waypoints))
        self.threats = Threats()
        self.estimate = self.estimator.update(0.0)
        self.controller.reset(self.estimate)
        self._control_dt = 1.0 / af.control_hz
        self._setpoint: dict = {}
        self._commands: dict[str, float] = {}

    # -- tasks -------------------------------------------------------------------------------
    def schedule(self, sched: LockstepScheduler, log_hz: float) -> None:
        af, n = self.airframe, self.name
        sched.add_plant(f"{n}.plant", af.plant_hz, self.plant.step)
        sched.add_task(f"{n}.estimator", af.control_hz, Stage.ESTIMATE, self._estimate)
        sched.add_task(f"{n}.planner", self.cfg.planner.rate_hz, Stage.PLAN, self._plan)
        sched.add_task(f"{n}.control", af.control_hz, Stage.CONTROL, self._control)
        sched.add_task(f"{n}.log", log_hz, Stage.LOG, self._log)

    def _estimate(self, t: float) -> None:
        self.estimate = self.estimator.update(t)

    def _plan(self, t: float) -> None:
        t0 = time.perf_counter()
        plan: Plan = self.planner.plan(self.estimate, self.threats, t)
        latency = time.perf_counter() - t0
        self.follower.set_plan(plan)
        self.logw.plan(plan, latency)
        self.recorder.latency(latency)

    def _control(self, t: float) -> None:
        sp, passed = self.follower.update(self.estimate)
        for label in passed:
            if label >= 0 and self.mission.mark_reached(label, t):
                total = len(self.mission.waypoints)
                self.log.event(t, f"{self.name}: waypoint {label + 1}/{total} reached", name=self.name)
                self.recorder.reached(t)
                if self.mission.complete:
                    self.log.event(t, f"{self.name}: mission complete", name=self.name)
        cmds = self.controller.update(self.estimate, sp, self._control_dt)
        self.plant.set_many(cmds)
        self._setpoint = setpoint_dict(sp, leg=self.follower.leg, cross_track_m=self.follower.cross_track_m,
                                       turning=self.follower.turning)
        self._commands = cmds

    def _log(self, t: float) -> None:
        truth = self.plant.truth()
        if not all(math.isfinite(x) for x in (*truth.pos_ned, *truth.vel_ned, *truth.euler)):
            self.log.event(t, f"{self.name}: state is not finite", level="error", name=self.name)
            raise SimulationDiverged(f"{self.name}: state went non-finite at t={t:.2f} s")
        self.recorder.state(self.logw.truth(truth), self._setpoint)
        self.logw.control(t, self._setpoint, self._commands, dict(self.controller.debug))
        m = self.mission
        self.logw.mission(t, m.next_index, len(m.waypoints), m.complete)
