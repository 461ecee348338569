"""One simulated vehicle: JSBSim plant, estimator, planner, plan follower, flight controller.

Data flow per tick (see architecture.md): the estimator produces the estimate; the planner
(at its rate) turns estimate + sensed threats into a Plan; the follower turns the plan into a
setpoint; the controller turns setpoint + estimate into JSBSim property commands. Only the
logger reads the plant's truth.
"""

from __future__ import annotations

import math
import time
from datetime import UTC, datetime

import numpy as np

from aircraft.nav_inputs import ATTITUDE_SOURCE, ESTIMATE_PROPERTIES, estimate_values
from aircraft.quadrotor.controller import MultirotorController
from aircraft.registry import get_airframe
from sim import log_schemas as S
from sim import scenario as sc
from sim.core.mission import Mission
from sim.core.plan import ObservingPlanner, Plan, Planner, Threats
from sim.core.setpoints import MultirotorSetpoint
from sim.energy.altitude_schedule import AltitudeManager, AltitudeSchedule
from sim.energy.params import EnergyParams
from sim.energy.power_system import PowerSystem
from sim.estimation.sensor_estimator import SensorEstimator
from sim.geodesy import GeoPoint
from sim.mcap_log import McapLog
from sim.planner_records import RecordSink
from sim.planner_registry import PLANNERS
from sim.position_planners import GotoPlanner, HoldPositionPlanner
from sim.replay.trace import CHUNK, TraceRecorder
from sim.scheduler import LockstepScheduler, Stage
from sim.sensors.faults import SensorFault
from sim.vehicle_commands import apply_command
from sim.vehicle_log import VehicleLogWriter, setpoint_record
from sim.vehicle_setup import build_plant, make_estimator, make_follower, mission_from_config, scenario_planner
from sim.wind_field import WindField

_METRIC_BLOCK = math.gcd(32, CHUNK)  # log ticks per hand-over to the metrics recorder


class SimulationDiverged(RuntimeError):
    """The plant's state went non-finite."""


class Vehicle:
    # the inner loops close on the estimate when the estimator has sensors; False keeps them on
    # JSBSim's truth (the comparison of tests/test_inner_loop_estimate.py and the benchmark)
    inner_loops_on_estimate = True

    def __init__(self, cfg: sc.VehicleSpec, origin: GeoPoint, log: McapLog, seed: int, wind: sc.Wind = sc.Wind()):
        """``seed``: this vehicle's own seed (its JSBSim turbulence and sensor noise)."""
        self.name = cfg.name
        self.cfg = cfg
        self.origin = origin
        self.airframe = af = get_airframe(cfg.aircraft)
        self.log = log
        self.logw = VehicleLogWriter(log, cfg.name)
        self.planner_records = RecordSink(log, f"/{cfg.name}/plan", origin)
        self.wind = WindField(wind)
        self.plant = build_plant(cfg, af, origin, wind, self.wind, seed, lambda text: self.event(0.0, text))
        self.wind_spec = wind  # the planners' forecast
        self.mission = mission_from_config(cfg, origin)
        self.estimator = make_estimator(cfg.estimator, self.plant, af, seed, origin, cfg.sensors)
        self._inner_set = []  # setters of the inner loops' estimate inputs (aircraft.nav_inputs)
        if isinstance(self.estimator, SensorEstimator) and self.inner_loops_on_estimate:
            self.plant[ATTITUDE_SOURCE] = 1.0
            self._inner_set = [n.set_double_value for n in self.plant.property_nodes(ESTIMATE_PROPERTIES)]
        self.controller = af.make_controller(cfg.gains)
        self.planner: Planner = self.make_mission_planner()
        self._planner_logged: Planner | None = None  # the planner of the last logged call
        self.mode = "AUTO"  # AUTO: the mission; HOLD: hover in place; GUIDED: ground-station targets
        self.estimate = self.estimator.update(0.0)
        self.follower = make_follower(cfg, af, self.controller, self.mission, origin)
        if af.kind == "fixed_wing":
            self.controller.reset(self.estimate)
            self._setpoint_schema = S.FIXED_WING_SETPOINT
        else:
            self._multirotor().reset(self.estimate, landed=cfg.initial.on_ground)
            self._setpoint_schema = S.MULTIROTOR_SETPOINT
        self.power = self._make_power_system(log)
        sched = cfg.energy.altitude_schedule
        self.altitude_manager = (
            AltitudeManager(
                AltitudeSchedule(sched.floor, sched.ceiling, sched.soc_high, sched.soc_low), self.power.battery.soc
            )
            if sched is not None and self.power is not None
            else None
        )
        self.recorder = TraceRecorder(cfg.name, af.kind, len(self.mission.waypoints))
        self._metric_ticks: list[tuple] = []  # ticks logged, not yet handed to the recorder
        self.threats = Threats()
        self._control_dt = 1.0 / af.control_hz
        self._setpoint: dict = {}
        self._commands: dict[str, float] = {}
        self._mission_logged: tuple[int, bool] | None = None

    def _make_power_system(self, log: McapLog) -> PowerSystem | None:
        path = self.airframe.energy_file
        if path is None or not self.cfg.energy.enabled:
            return None
        epoch = datetime.fromtimestamp(log.epoch_ns / 1e9, tz=UTC)
        return PowerSystem(EnergyParams.load(path), epoch, self.cfg.energy.initial_soc)

    def make_mission_planner(self) -> Planner:
        """The scenario's planner for the current mission."""
        return scenario_planner(
            self.cfg, self.mission, self.airframe, self.controller.gains, self.wind_spec, self.origin.alt_m
        )

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

    def apply_command(self, cmd: object, t: float) -> bool:
        """Act on a ground-station command at sim time ``t`` [s] (``sim.vehicle_commands``);
        True when the mission changed."""
        return apply_command(self, cmd, t)

    # -- tasks -------------------------------------------------------------------------------
    def schedule(self, sched: LockstepScheduler, log_hz: float) -> None:
        af, n = self.airframe, self.name
        sched.add_plant(f"{n}.plant", af.plant_hz, self.plant.step)
        if self.wind.varies:  # error <= max shear * climb rate / control rate (sim.wind_field)
            sched.add_task(f"{n}.wind", af.control_hz, Stage.ENVIRONMENT, self._wind)
        if isinstance(self.estimator, SensorEstimator):
            sched.add_task(f"{n}.sense", self.estimator.sense_hz, Stage.SENSE, self._sense, plant=f"{n}.plant")
        sched.add_task(f"{n}.estimator", af.control_hz, Stage.ESTIMATE, self._estimate)
        if isinstance(self.planner, ObservingPlanner):  # at a call's time the observation comes first, as re-run
            sched.add_task(f"{n}.observe", self.planner.observe_hz, Stage.PLAN, self.observe_now)
        sched.add_task(f"{n}.planner", self.cfg.planner.rate_hz, Stage.PLAN, self.plan_now)
        sched.add_task(f"{n}.control", af.control_hz, Stage.CONTROL, self._control)
        if self.power is not None:
            sched.add_task(f"{n}.energy", af.control_hz, Stage.CONTROL, self._energy)
        sched.add_task(f"{n}.log", log_hz, Stage.LOG, self._log)

    def _wind(self, t: float) -> None:
        self.plant.set_wind(self.wind.at(self.plant.truth().alt_msl_m, t))

    def _sense(self, t: float) -> None:
        """Sample the sensors; hand the inner loops the newest gyro-propagated attitude and
        bias-corrected rates (held by the FCS until the next gyro sample)."""
        est = self.estimator
        assert isinstance(est, SensorEstimator)
        est.sense(t)
        sample = est.attitude.sample
        if self._inner_set and sample is not None and sample.t == t:
            for put, value in zip(self._inner_set, estimate_values(sample), strict=True):
                put(value)

    def _estimate(self, t: float) -> None:
        self.estimate = self.estimator.update(t)

    def observe_now(self, t: float) -> None:
        """Hand an observing planner the estimate at ``t`` [s] and log it, once the planner has
        been called (a planner built anew, after a mode change or a mission upload, starts
        observing with its first call, so a re-run can feed the logged estimates to the planner
        that was flying)."""
        p = self.planner
        if isinstance(p, ObservingPlanner) and p is self._planner_logged:
            p.observe(self.estimate, t)
            self.logw.plan_observation(t, self.estimate)

    def plan_now(self, t: float) -> None:
        """Call the planner now and hand its plan to the follower. Logged per call: the planner's
        inputs; per new plan (made at this call, ``plan.t == t``): the plan and the call's
        wall-clock latency; a call that kept the previous plan counts as a cache hit."""
        self.logw.threats(t, self.threats)
        t0 = time.perf_counter()
        plan: Plan = self.planner.plan(self.estimate, self.threats, t)
        latency = time.perf_counter() - t0
        new_plan = plan.t == t
        fresh, self._planner_logged = self.planner is not self._planner_logged, self.planner
        setup = self.planner.setup() if fresh and isinstance(self.planner, HoldPositionPlanner | GotoPlanner) else None
        self.logw.plan_input(t, self.planner.name, self.estimate, self.mission, new_plan, fresh, setup)
        if plan is not self.follower.plan:  # a kept plan keeps the follower's progress along it
            self.follower.set_plan(plan)
        if new_plan:
            self.logw.plan(plan)
            self.logw.latency(t, latency)
            self.recorder.latency(latency)
        else:
            self.recorder.cache_hit()
        entry = PLANNERS.get(self.planner.name)  # ground-station mode planners have no records
        if entry is not None and entry.records is not None:
            entry.records(self.planner_records, self.planner, plan, t)

    def _multirotor(self) -> MultirotorController:
        """The controller of a multirotor (landing and take-off state, its limits)."""
        if not isinstance(self.controller, MultirotorController):
            raise TypeError(f"{self.name}: {type(self.controller).__name__} is not a multirotor controller")
        return self.controller

    def event(self, t: float, text: str) -> None:
        """A ``/log`` event of this vehicle at sim time ``t`` [s]."""
        self.log.event(t, f"{self.name}: {text}", name=self.name)

    def _control(self, t: float) -> None:
        m = self.mission
        sp, passed = self.follower.update(self.estimate, t, self._control_dt)
        for label in passed:
            if label >= 0 and m.mark_reached(label, t):
                self.event(t, f"waypoint {label + 1}/{len(m.waypoints)} reached")
                self.recorder.reached(t)
        if self.cfg.mission.repeat and m.waypoints_done:
            m = self._repeat_mission(t)
        if m.land and m.waypoints_done:  # descend, and stay down once landed
            last = m.waypoints[-1]
            descent = self._multirotor().gains.limits.max_descent
            sp = MultirotorSetpoint(np.array([last[0], last[1], np.nan]), np.array([0.0, 0.0, descent]), float("nan"))
        if self.altitude_manager is not None and self.power is not None:
            sp.altitude_m = self.altitude_manager.altitude(self.power.battery.soc)
        cmds = self.controller.update(self.estimate, sp, self._control_dt)
        if m.land and m.waypoints_done and m.landed_t is None and self._multirotor().landed:
            m.landed_t = t
            self.event(t, "landed")
        if m.check_complete(t):
            self.event(t, "mission complete")
            self.recorder.complete(t)
        self.plant.set_many(cmds)
        self._setpoint = setpoint_record(sp, self.follower, self.origin)
        self._commands = cmds

    def _energy(self, t: float) -> None:
        """Step the power system over the coming control period; an empty battery stops the
        motors (motor health 0) for the rest of the run."""
        power = self.power
        if power is None:
            return
        was_depleted = power.depleted
        shaft = [self.plant[f"propulsion/engine[{i}]/power-hp"] for i in range(self.plant.engine_count)]
        rec = power.step(self.plant.truth(), shaft, self._control_dt)
        if rec.depleted and not was_depleted:
            self.plant.set_many({f"ap/motor-health[{i}]": 0.0 for i in range(self.plant.engine_count)})
            self.log.event(
                t, f"{self.name}: energy_depleted (battery empty), motors stopped", level="warning", name=self.name
            )

    def _repeat_mission(self, t: float) -> Mission:
        """The same waypoints again, the first leg from the last waypoint (mission.repeat)."""
        m = self.mission
        self.mission = Mission(m.waypoints, m.cruise_speed, m.acceptance_radius, start=m.waypoints[-1].copy())
        self.planner = self.make_mission_planner()
        self.event(t, "mission repeated")
        self.plan_now(t)
        return self.mission

    def _log(self, t: float) -> None:
        truth = self.plant.truth()
        motion = truth.pos_ned.tolist() + truth.vel_ned.tolist() + truth.euler.tolist()
        if not math.isfinite(sum(motion)):  # NaN and infinities propagate to the sum
            self.log.event(t, f"{self.name}: state is not finite", level="error", name=self.name)
            raise SimulationDiverged(f"{self.name}: state went non-finite at t={t:.2f} s")
        track = self.follower.track_error(truth.pos_ned)
        estimator = self.estimator if isinstance(self.estimator, SensorEstimator) else None
        control = (self._setpoint, self._setpoint_schema, self._commands, dict(self.controller.debug))
        energy = None if self.power is None else self.power.record
        m = self.mission
        status = (m.next_index, m.complete)
        mission = None
        if status != self._mission_logged:
            self._mission_logged = status
            mission = (m.next_index, len(m.waypoints), m.complete)
        track_leg = (track, self.follower.leg)
        sigma3 = self.logw.tick(t, truth, track_leg, self.estimate, estimator, control, energy, mission)
        ticks = self._metric_ticks
        ticks.append((truth, self._setpoint, self._commands, track, self.estimate, sigma3))
        if len(ticks) >= _METRIC_BLOCK:
            self.feed_metrics()

    def feed_metrics(self) -> None:
        """Hand the ticks logged since the last call to the metrics recorder (every
        :data:`_METRIC_BLOCK` ticks, and before its last flush): a block at a time costs less
        than a tick at a time between simulation steps. The recorder keeps the ticks' states,
        setpoint records and commands, which are not changed later; its chunks are cut at the
        same ticks as when fed each tick (the block divides the chunk)."""
        rec = self.recorder
        for truth, setpoint, commands, track, estimate, sigma3 in self._metric_ticks:
            rec.state(truth, setpoint, commands, track)
            rec.estimate(estimate, sigma3)
        self._metric_ticks = []
