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
from guidance.fixed_wing_follower import FixedWingPlanFollower
from guidance.l1 import L1Guidance
from guidance.multirotor_follower import MultirotorPlanFollower
from sim import log_schemas as S
from sim import scenario as sc
from sim.core.mission import Mission
from sim.core.plan import Plan, Threats
from sim.core.setpoints import MultirotorSetpoint
from sim.environment import apply_steady_wind, apply_turbulence
from sim.estimation.sensor_estimator import SensorEstimator, SensorEstimatorConfig
from sim.estimator import PerfectEstimator
from sim.geodesy import GeoPoint, geodetic_to_ned, ned_to_geodetic
from sim.jsbsim_plant import InitialConditions, JSBSimPlant
from sim.mavlink.commands import Arm, MissionUpload, PositionTarget, SetMode
from sim.mcap_log import McapLog
from sim.planner_log import PlannerLogger
from sim.planner_registry import make_planner
from sim.position_planners import GotoPlanner, HoldPositionPlanner
from sim.replay.trace import TraceRecorder
from sim.scheduler import LockstepScheduler, Stage
from sim.sensors.faults import SensorFault
from sim.vehicle_log import VehicleLogWriter


class SimulationDiverged(RuntimeError):
    """The plant's state went non-finite."""


def _ned(north: float, east: float, altitude: float, origin: GeoPoint) -> np.ndarray:
    return np.array([north, east, origin.alt_m - altitude])


def _json_num(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def mission_from_config(cfg: sc.Vehicle, origin: GeoPoint) -> Mission:
    """The vehicle's mission in the local-level NED frame, starting at its initial position."""
    m, ini = cfg.mission, cfg.initial
    return Mission(
        waypoints=np.array([_ned(w.north, w.east, w.altitude, origin) for w in m.waypoints]),
        cruise_speed=m.cruise_speed,
        acceptance_radius=m.acceptance_radius,
        start=_ned(ini.north, ini.east, ini.altitude, origin),
        hold_s={k: w.hold for k, w in enumerate(m.waypoints) if w.hold > 0},
        land=m.land,
    )


class Vehicle:
    def __init__(self, cfg: sc.Vehicle, origin: GeoPoint, log: McapLog, seed: int, wind: sc.Wind = sc.Wind()):
        """``seed``: this vehicle's own seed (its JSBSim turbulence and sensor noise)."""
        self.name = cfg.name
        self.cfg = cfg
        self.origin = origin
        self.airframe = af = get_airframe(cfg.aircraft)
        self.log = log
        self.logw = VehicleLogWriter(log, cfg.name)
        self.planner_log = PlannerLogger(log, cfg.name, origin)
        self.plant = JSBSimPlant(af.jsbsim_model, 1.0 / af.plant_hz, origin, af.folder)
        apply_steady_wind(self.plant, wind)
        ini = cfg.initial
        start = _ned(ini.north, ini.east, ini.altitude, origin)
        lat, lon, alt = ned_to_geodetic(start, origin)
        self.plant.initialise(
            InitialConditions(
                position=GeoPoint(float(lat), float(lon), float(alt)),
                tas_mps=ini.airspeed,
                heading_rad=ini.heading,
                roll_rad=ini.roll,
                pitch_rad=ini.pitch,
                on_ground=ini.on_ground,
                terrain_alt_m=origin.alt_m,
            )
        )
        if ini.trim if ini.trim is not None else af.kind == "fixed_wing":
            self.plant.trim()
        apply_turbulence(self.plant, wind, seed)
        m = cfg.mission
        self.mission = mission_from_config(cfg, origin)
        self.estimator = self._make_estimator(cfg.estimator, seed)
        self.controller = af.make_controller(cfg.gains)
        self.planner = self._make_planner()
        self.mode = "AUTO"  # AUTO: the mission; HOLD: hover in place; GUIDED: ground-station targets
        self.estimate = self.estimator.update(0.0)
        if af.kind == "fixed_wing":
            self.follower = FixedWingPlanFollower(
                L1Guidance.for_airframe(self.controller), m.cruise_speed, m.acceptance_radius, origin.alt_m
            )
            self.controller.reset(self.estimate)
            self._setpoint_schema = S.FIXED_WING_SETPOINT
        else:
            lim = self.controller.gains.limits
            self.follower = MultirotorPlanFollower(
                m.cruise_speed,
                lim.max_climb,
                lim.max_descent,
                m.acceptance_radius,
                self.mission.hold_s,
                yaw_rad={k: w.yaw for k, w in enumerate(m.waypoints) if w.yaw is not None},
                step=m.guidance == "step",
            )
            self.controller.reset(self.estimate, landed=ini.on_ground)
            self._setpoint_schema = S.MULTIROTOR_SETPOINT
        self.recorder = TraceRecorder(cfg.name, af.kind, len(self.mission.waypoints))
        self.threats = Threats()
        self._control_dt = 1.0 / af.control_hz
        self._setpoint: dict = {}
        self._commands: dict[str, float] = {}
        self._mission_logged: tuple[int, bool] | None = None

    def _make_planner(self):
        return make_planner(
            self.cfg.planner.type,
            self.mission,
            self.airframe.kind,
            self.cfg.planner.options,
            getattr(self.controller.gains, "roll_limit_rad", np.radians(20.0)),
        )

    def _make_estimator(self, kind: str, seed: int):
        """``ekf``: sensor models + INS/GNSS EKF (the default: the loop closes on estimates);
        ``perfect``: ideal sensors (controller characterisation against the model)."""
        if kind == "perfect":
            return PerfectEstimator(self.plant)
        cfg = SensorEstimatorConfig.for_kind(self.airframe.kind)
        cfg.check_rates(self.airframe.plant_hz)
        rng = np.random.default_rng(np.random.SeedSequence([seed, 1]))  # not the turbulence stream
        return SensorEstimator(self.plant, cfg, rng, self.origin, self.plant.truth())

    def inject_sensor_fault(self, fault) -> None:
        """A scenario sensor fault (gnss_loss, sensor_bias, sensor_stuck) into the sensor models."""
        end = math.inf if fault.duration is None else fault.at + fault.duration
        if isinstance(fault, sc.GnssLoss):
            self.estimator.inject("gnss", SensorFault(kind="dropout", t_start=fault.at, t_end=end))
            return
        sensor = {"accel": "imu", "gyro": "imu"}.get(fault.sensor, fault.sensor)
        if isinstance(fault, sc.SensorStuck):
            self.estimator.inject(sensor, SensorFault(kind="stuck", t_start=fault.at, t_end=end))
            return
        value = fault.bias
        if fault.sensor in ("accel", "gyro"):  # the IMU's output is accel x, y, z then gyro x, y, z
            b = np.broadcast_to(np.asarray(value, float), (3,))
            value = (*b, 0.0, 0.0, 0.0) if fault.sensor == "accel" else (0.0, 0.0, 0.0, *b)
        self.estimator.inject(sensor, SensorFault(kind="bias_step", t_start=fault.at, t_end=end, value=value))

    @property
    def armed(self) -> bool:
        """Motors armed (fixed wing: always, its motors never stop in flight)."""
        return bool(getattr(self.controller, "armed", True))

    # -- ground-station commands (MAVLink) -----------------------------------------------------
    def apply_command(self, cmd, t: float) -> bool:
        """Act on a ground-station command at sim time ``t`` [s]; every one is logged as an
        event. Returns True when the mission changed."""
        multirotor = self.airframe.kind == "multirotor"
        if isinstance(cmd, MissionUpload):
            wps = geodetic_to_ned(*np.asarray(cmd.waypoints, float).T, self.origin)
            m = self.mission
            self.mission = Mission(
                wps, m.cruise_speed, m.acceptance_radius, start=self.estimate.pos_ned.copy(), land=m.land
            )
            self.planner = self._make_planner()
            if multirotor:
                self.follower.set_waypoint_attributes({}, {})
            self.recorder.waypoints_total = len(wps)
            self.mode = "AUTO"
            self._event(t, f"mission uploaded: {len(wps)} waypoints, mode AUTO")
            self._plan(t)
            return True
        if isinstance(cmd, SetMode):
            if cmd.name == "AUTO":
                self.planner = self._make_planner()
            elif cmd.name in ("HOLD", "GUIDED") and multirotor:
                self.planner = HoldPositionPlanner(self.estimate.pos_ned)
            else:
                self._event(t, f"mode {cmd.name} refused: not available for a {self.airframe.kind}")
                return False
            self.mode = cmd.name
            self._event(t, f"mode {cmd.name}")
            self._plan(t)
            return False
        if isinstance(cmd, PositionTarget):
            if self.mode != "GUIDED" or not multirotor or cmd.pos_ned is None or np.isnan(cmd.pos_ned).any():
                self._event(t, "position target ignored (needs GUIDED mode, a multirotor and a full position)")
                return False
            self.planner = GotoPlanner(self.estimate.pos_ned, cmd.pos_ned, self.mission.cruise_speed)
            self._event(t, "position target: " + ", ".join(f"{x:.1f}" for x in cmd.pos_ned) + " m NED")
            self._plan(t)
            return False
        if isinstance(cmd, Arm):
            # arming follows from the mission (take-off demand); disarming in flight is refused
            self._event(
                t,
                f"{'arm' if cmd.arm else 'disarm'} request noted; motors follow the flight "
                f"controller (armed: {self.armed})",
            )
            return False
        raise TypeError(f"unknown command {cmd!r}")

    # -- tasks -------------------------------------------------------------------------------
    def schedule(self, sched: LockstepScheduler, log_hz: float) -> None:
        af, n = self.airframe, self.name
        sched.add_plant(f"{n}.plant", af.plant_hz, self.plant.step)
        if isinstance(self.estimator, SensorEstimator):
            sched.add_task(f"{n}.sense", self.estimator.sense_hz, Stage.SENSE, self.estimator.sense)
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
        self.logw.threats(t, self.threats)
        self.logw.plan(plan, latency)
        self.planner_log.write(self.planner, plan, t)
        self.recorder.latency(latency)

    def _event(self, t: float, text: str) -> None:
        self.log.event(t, f"{self.name}: {text}", name=self.name)

    def _control(self, t: float) -> None:
        m = self.mission
        sp, passed = self.follower.update(self.estimate, t, self._control_dt)
        for label in passed:
            if label >= 0 and m.mark_reached(label, t):
                self._event(t, f"waypoint {label + 1}/{len(m.waypoints)} reached")
                self.recorder.reached(t)
        if m.land and m.waypoints_done:  # descend, and stay down once landed
            last = m.waypoints[-1]
            descent = self.controller.gains.limits.max_descent
            sp = MultirotorSetpoint(np.array([last[0], last[1], np.nan]), np.array([0.0, 0.0, descent]), float("nan"))
        cmds = self.controller.update(self.estimate, sp, self._control_dt)
        if m.land and m.waypoints_done and m.landed_t is None and self.controller.landed:
            m.landed_t = t
            self._event(t, "landed")
        if m.check_complete(t):
            self._event(t, "mission complete")
            self.recorder.complete(t)
        self.plant.set_many(cmds)
        self._setpoint = self._setpoint_record(sp)
        self._commands = cmds

    def _setpoint_record(self, sp) -> dict:
        f = self.follower
        common = {"leg": f.leg, "cross_track_m": f.cross_track_m, "turning": f.turning}
        if isinstance(sp, MultirotorSetpoint):
            d = float(sp.pos_ned[2])
            return {
                "pos_ned": [_json_num(x) for x in sp.pos_ned],
                "vel_ned": [float(x) for x in sp.vel_ned],
                "yaw_rad": _json_num(sp.yaw_rad),
                "altitude_m": _json_num(self.origin.alt_m - d),
                **common,
            }
        return {"roll_rad": sp.roll_rad, "altitude_m": sp.altitude_m, "tas_mps": sp.tas_mps, **common}

    def _log(self, t: float) -> None:
        truth = self.plant.truth()
        if not math.isfinite(float(truth.pos_ned.sum() + truth.vel_ned.sum() + truth.euler.sum())):  # NaN/inf propagate
            self.log.event(t, f"{self.name}: state is not finite", level="error", name=self.name)
            raise SimulationDiverged(f"{self.name}: state went non-finite at t={t:.2f} s")
        track = self.follower.track_error(truth.pos_ned)
        self.logw.tracking(t, track, self.follower.leg)
        self.recorder.state(self.logw.truth(truth), self._setpoint, self._commands, track)
        est_logged = self.logw.estimate(self.estimate)
        sigma3 = None
        if isinstance(self.estimator, SensorEstimator):
            est = self.estimator
            sigma3 = est.three_sigma()
            self.logw.sensors(t, est.measurements(), sigma3, est.biases())
        self.recorder.estimate(est_logged, sigma3)
        self.logw.control(t, self._setpoint, self._setpoint_schema, self._commands, dict(self.controller.debug))
        m = self.mission
        status = (m.next_index, m.complete)
        if status != self._mission_logged:
            self._mission_logged = status
            self.logw.mission(t, m.next_index, len(m.waypoints), m.complete)
