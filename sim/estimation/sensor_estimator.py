"""One vehicle's sensors + INS/GNSS EKF as a single component the simulation loop calls.

Tasks the world schedules (both rates must divide the plant rate; the config checks it with
:meth:`SensorEstimatorConfig.check_rates`)::

    est = SensorEstimator(plant, SensorEstimatorConfig.for_kind(airframe.kind), rng, origin, initial)
    sched.add_task(f"{name}.sense", est.sense_hz, Stage.SENSE, est.sense)          # IMU rate
    sched.add_task(f"{name}.estimator", control_hz, Stage.ESTIMATE, est.update)    # -> VehicleState

``sense(t)`` samples the IMU (specific force and body rates only: seven JSBSim property
reads) through its error model, appends the output to the current fusion interval, polls the
aiding sensors when one is due (GNSS, baro, airspeed, magnetometer, from a full truth sample),
and at every fusion tick (``fusion_hz``, a divisor of the IMU rate) runs ONE EKF predict with
the interval's trapezoidal average (PX4 EKF2
style downsampled IMU: the mid-interval attitude makes this exact for constant rate and
specific force, coning/sculling are second order) and ONE stacked update with every aiding
measurement delivered in the interval. Every gyro sample also updates :attr:`attitude`
(:class:`sim.estimation.gyro_attitude.GyroAttitude`): the inner loops' attitude, restarted from
the posterior at each fusion and propagated with the bias-corrected gyro in between, and the
bias-corrected rates. ``update(t)`` returns the estimate at ``t`` (calls
``sense(t)`` first if the world did not). The EKF (:class:`sim.estimation.ins_ekf.InsEkf`)
keeps its per-sample filterpy path for stand-alone use; this component uses its fast paths.

Logging accessors: :meth:`measurements` (delivered since the last call, plain floats; the IMU
as one averaged record per fusion interval), :meth:`three_sigma`, :meth:`biases`.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike
from pydantic import Field, model_validator

from sim.core.state import VehicleState
from sim.estimation.gyro_attitude import GyroAttitude
from sim.estimation.ins_ekf import InsEkf, InsEkfConfig
from sim.estimation.ins_model import N, sigma_bounds
from sim.geodesy import GeoPoint
from sim.jsbsim_plant import JSBSimPlant
from sim.sensors.airspeed import AirspeedConfig
from sim.sensors.baro import BaroConfig
from sim.sensors.config import SensorConfigError, StrictConfig
from sim.sensors.faults import SensorFault
from sim.sensors.gnss import GnssConfig
from sim.sensors.imu import Imu, ImuConfig
from sim.sensors.magnetometer import MagnetometerConfig
from sim.sensors.measurements import AirspeedSample, BaroSample, GnssFix, MagSample, Measurement
from sim.sensors.suite import SensorSuite, SensorSuiteConfig
from sim.sensors.truth import TruthSampler

MeasurementLog = dict[str, list[Any]]  # per sensor: "imu" (t, dt, mean) tuples, the others measurements

_EPS = 1e-9
_LBF = 4.4482216152605  # N per lbf
_SLUG = 14.593902937206364  # kg per slug
_IMU_PROPS = (
    "forces/fbx-total-lbs",
    "forces/fby-total-lbs",
    "forces/fbz-total-lbs",
    "inertia/mass-slugs",
    "velocities/p-rad_sec",
    "velocities/q-rad_sec",
    "velocities/r-rad_sec",
)


def normal_gravity(lat_deg: float, alt_m: float) -> float:
    """WGS84 normal gravity (Somigliana) with the free-air gradient [m/s^2]; what JSBSim's
    specific force implies at rest (checked: 9.7525 m/s^2 at 47 deg N, 18 km, within 3e-4)."""
    s2 = math.sin(math.radians(lat_deg)) ** 2
    return 9.7803253359 * (1.0 + 0.00193185265241 * s2) / math.sqrt(1.0 - 0.00669437999013 * s2) - 3.086e-6 * alt_m


class SensorEstimatorConfig(StrictConfig):
    """Sensor suite, filter and rates of one vehicle's estimator.

    ``ekf``: the filter's noise model; ``None`` takes it from the sensors
    (:meth:`InsEkfConfig.matching`). ``fusion_hz``: EKF predict/update rate, must divide the
    IMU rate (the IMU rate is the sense rate). ``local_gravity``: set the filter's gravity to
    the normal gravity at the initial position (JSBSim flies a round earth: at 18 km gravity is
    0.055 m/s^2 below standard). ``perturb_initial``: draw the initial estimate from the initial
    uncertainty around the given initial state (a realistic alignment error) instead of starting
    exactly on it.
    """

    sensors: SensorSuiteConfig
    ekf: InsEkfConfig | None = None
    fusion_hz: float = Field(gt=0.0)
    local_gravity: bool = True
    perturb_initial: bool = True

    @model_validator(mode="after")
    def _check(self) -> SensorEstimatorConfig:
        imu = self.sense_hz
        k = imu / self.fusion_hz
        if abs(k - round(k)) > 1e-9 or round(k) < 1:
            raise ValueError(f"fusion_hz ({self.fusion_hz:g}) must divide the IMU rate ({imu:g} Hz)")
        return self

    @property
    def sense_hz(self) -> float:
        """Rate of the ``sense`` task: the IMU rate [Hz]."""
        if self.sensors.imu is None:
            raise ValueError("sensors.imu is required (the filter is IMU-driven)")
        return self.sensors.imu.rate_hz

    def ekf_config(self) -> InsEkfConfig:
        return self.ekf if self.ekf is not None else InsEkfConfig.matching(self.sensors)

    def check_rates(self, plant_hz: float) -> None:
        """SensorConfigError unless every sensor rate and the fusion rate divide ``plant_hz``
        (the lockstep scheduler samples the plant at multiples of its step only)."""
        bad = []
        rates = {"fusion_hz": self.fusion_hz} | {
            f"{n}.rate_hz": getattr(self.sensors, n).rate_hz
            for n in SensorSuiteConfig.model_fields
            if getattr(self.sensors, n) is not None
        }
        for what, hz in rates.items():
            d = plant_hz / hz
            if abs(d - round(d)) > 1e-9:
                bad.append(f"{what}: {hz:g} Hz does not divide the plant rate {plant_hz:g} Hz")
        if bad:
            raise SensorConfigError("SensorEstimatorConfig: " + "; ".join(bad))

    @classmethod
    def for_kind(cls, kind: Literal["fixed_wing", "multirotor"], **overrides) -> SensorEstimatorConfig:
        """Defaults per airframe kind (rates dividing the registry's plant rates; the IMU at the
        plant rate, so the inner loops, which JSBSim runs every plant step, get a fresh gyro
        sample every step as an autopilot's rate loop does):
        - ``fixed_wing`` (HAPS, plant 120 Hz): IMU 120 Hz, EKF predict 10 Hz, GNSS, baro, pitot
          and magnetometer 5 Hz (slow dynamics; one stacked update every other fusion tick);
        - ``multirotor`` (plant 240 Hz): IMU 240 Hz, EKF 60 Hz, GNSS 5 Hz, baro and
          magnetometer 20 Hz, no pitot.
        ``overrides``: fields of this config (e.g. ``fusion_hz=20``, ``sensors=...``)."""
        if kind == "fixed_wing":
            sensors = SensorSuiteConfig(
                imu=ImuConfig(rate_hz=120.0),
                gnss=GnssConfig(rate_hz=5.0),
                baro=BaroConfig(rate_hz=5.0),
                airspeed=AirspeedConfig(rate_hz=5.0),
                mag=MagnetometerConfig(rate_hz=5.0),
            )
            base = {"sensors": sensors, "fusion_hz": 10.0}
        elif kind == "multirotor":
            sensors = SensorSuiteConfig(
                imu=ImuConfig(rate_hz=240.0),
                gnss=GnssConfig(rate_hz=5.0),
                baro=BaroConfig(rate_hz=20.0),
                airspeed=None,
                mag=MagnetometerConfig(rate_hz=20.0),
            )
            base = {"sensors": sensors, "fusion_hz": 60.0}
        else:
            raise SensorConfigError(f"SensorEstimatorConfig: unknown airframe kind {kind!r} (fixed_wing, multirotor)")
        return cls.build(**(base | overrides))


def _floats(v: ArrayLike) -> list[float]:
    """Plain floats of a vector (``tolist`` is ~10x faster than a comprehension)."""
    return np.asarray(v, dtype=float).tolist()


class SensorEstimator:
    """Sensors + EKF of one vehicle; implements :class:`sim.estimator.Estimator`.

    ``rng`` feeds everything random (two children: the sensor suite, the initial alignment
    error); ``origin`` is the scenario origin; ``initial`` the vehicle's initial state (e.g.
    ``plant.truth()`` after trim, or the scenario's initial conditions).
    """

    name = "sensor_ekf"

    def __init__(
        self,
        plant: JSBSimPlant,
        config: SensorEstimatorConfig,
        rng: np.random.Generator,
        origin: GeoPoint,
        initial: VehicleState,
    ):
        self.cfg = config
        self.plant = plant
        r_suite, r_init = rng.spawn(2)
        self.suite = SensorSuite(config.sensors, r_suite)
        s = self.suite.sensors
        imu = s.get("imu")
        if not isinstance(imu, Imu):
            raise SensorConfigError("SensorEstimator: sensors.imu is required (the filter is IMU-driven)")
        self.imu = imu
        self._aiding = [x for n, x in s.items() if n != "imu"]
        ecfg = config.ekf_config()
        if config.local_gravity:
            ecfg = ecfg.model_copy(update={"gravity_mps2": normal_gravity(origin.lat_deg, initial.alt_msl_m)})
        init = initial
        if config.perturb_initial:
            tilt, yaw = ecfg.init_tilt_std_rad, ecfg.init_yaw_std_rad
            init = replace(  # drawn in this order: position, velocity, attitude
                initial,
                pos_ned=initial.pos_ned + r_init.normal(0.0, ecfg.init_pos_std_m, 3),
                vel_ned=initial.vel_ned + r_init.normal(0.0, ecfg.init_vel_std_mps, 3),
                euler=initial.euler + r_init.normal(0.0, 1.0, 3) * [tilt, tilt, yaw],
            )
        self.ekf = InsEkf(ecfg, init, origin)
        self._imu_get = [n.get_double_value for n in plant.property_nodes(_IMU_PROPS)]
        self._truth = TruthSampler(plant)
        self._imu_period = 1.0 / config.sense_hz
        self._fuse_period = 1.0 / config.fusion_hz
        self._imu_next = -math.inf
        self._fuse_next = -math.inf
        self._aid_next = -math.inf
        self._t_sensed = -math.inf
        self._block: list[list[float]] = []  # the fusion interval's IMU outputs (accel, gyro)
        self._t_gyro = -math.inf  # time of the newest gyro sample [s]
        # inner-loop inputs: the attitude propagated with the bias-corrected gyro between fusions
        self.attitude = GyroAttitude(self.ekf.nav.q, tuple(self.ekf.nav.bg.tolist()))
        self._fused: tuple[float, list[float]] | None = None  # last fusion time [s], its newest IMU sample
        self._inbox: list[Measurement] = []
        self._log: MeasurementLog = {}
        self._cache: tuple[float, int, VehicleState] | None = None
        self._n_fusions = 0

    @property
    def sense_hz(self) -> float:
        return self.cfg.sense_hz

    @property
    def fusion_hz(self) -> float:
        return self.cfg.fusion_hz

    def inject(self, sensor: str, fault: SensorFault) -> None:
        """Schedule a fault on ``imu``, ``gnss``, ``baro``, ``airspeed`` or ``mag``."""
        self.suite.inject(sensor, fault)

    # -- tasks --------------------------------------------------------------------------------
    def sense(self, t: float) -> None:
        """IMU-rate task: sample the sensors due at ``t`` [s]; run the EKF at fusion ticks."""
        if t <= self._t_sensed + _EPS:
            return
        self._t_sensed = t
        gyro = None
        if t + _EPS >= self._imu_next:
            fx, fy, fz, mass, p, q, r = [get() for get in self._imu_get]
            k = _LBF / (mass * _SLUG)
            row = self.imu.measure_one(t, (fx * k, fy * k, fz * k, p, q, r), self._imu_period)
            if row is not None:  # a sample a fault dropped leaves the inner loops on the previous one
                self._block.append(row)
                gyro = (row[3], row[4], row[5])
            self._imu_next = (math.floor((t + _EPS) / self._imu_period) + 1) * self._imu_period
        if t + _EPS >= self._aid_next:
            self._poll_aiding(t)
        if t + _EPS >= self._fuse_next:
            self._fuse_next = (math.floor((t + _EPS) / self._fuse_period) + 1) * self._fuse_period
            self._fuse(t)
            if self._fused is not None:
                nav = self.ekf.nav
                prev = self._fused[1]
                w = gyro if gyro is not None else (prev[3], prev[4], prev[5])
                self.attitude.restart(t, nav.q, tuple(nav.bg.tolist()), w)
        elif gyro is not None:
            self.attitude.step(t, gyro, t - self._t_gyro)
        if gyro is not None:
            self._t_gyro = t

    def update(self, t: float) -> VehicleState:
        """Estimator protocol: the estimate at ``t`` [s] (for controllers, guidance, planners)."""
        if t > self._t_sensed + _EPS:
            self.sense(t)
        c = self._cache
        if c is not None and c[0] == t and c[1] == self._n_fusions:
            return c[2]
        est = self.ekf.state(t)
        self._cache = (t, self._n_fusions, est)
        return est

    # -- internals ----------------------------------------------------------------------------
    def _poll_aiding(self, t: float) -> None:
        due = any(t + _EPS >= s.next_sample_t() for s in self._aiding)
        truth = self._truth.sample() if due else None  # deliveries only: no truth needed
        nxt = math.inf
        for s in self._aiding:
            out = s.poll(truth) if truth is not None else s.deliver(t)
            if out:
                self._inbox.extend(out)
                self._log.setdefault(s.name, []).extend(out)
            nxt = min(nxt, s.next_sample_t(), s.next_delivery_t())
        self._aid_next = nxt

    def _fuse(self, t: float) -> None:
        block = self._block
        if block:
            last = block[-1]
            if self._fused is None:  # first sample: the start of the first interval
                self.ekf.t = t
            else:  # trapezoid over [previous interval's last sample, this one's samples]
                t_prev, prev = self._fused
                n = len(block)
                # per axis, the samples summed in order from -0.0 (the additive identity)
                cols = zip(*block, strict=True)
                mean = [(sum(col, -0.0) - 0.5 * a + 0.5 * b) / n for col, a, b in zip(cols, last, prev, strict=True)]
                dt = t - t_prev
                self.ekf.predict_mean(mean[:3], mean[3:], dt, t, last[3:])
                self._log.setdefault("imu", []).append((t, dt, mean))
            self._fused = (t, last)
            block.clear()
        elif self._fused is not None:  # IMU dropout: coast on the previous interval's last sample
            t_prev, prev = self._fused
            self.ekf.predict_mean(prev[:3], prev[3:], t - t_prev, t, prev[3:])
            self._fused = (t, prev)
        if self._inbox:
            self.ekf.fuse_batch(self._inbox)
            self._inbox.clear()
        self._n_fusions += 1

    # -- logging accessors --------------------------------------------------------------------
    def measurements(self) -> dict[str, list[dict]]:
        """Measurements delivered since the last call, per sensor, as plain floats (JSON-ready):
        ``imu``: one record per fusion interval (mean specific force [m/s^2] and rate [rad/s],
        body FRD, and the interval ``dt``); ``gnss``: ``pos_ned`` [m], ``vel_ned`` [m/s];
        ``baro``: ``pressure_pa``; ``airspeed``: ``diff_pressure_pa``; ``mag``: ``field_body_ut``.
        ``t`` is the time of validity [s]."""
        out: dict[str, list[dict]] = {}
        for name, items in self._log.items():
            if name == "imu":
                out[name] = [{"t": t, "dt": dt, "accel_body": mn[:3], "gyro_body": mn[3:]} for t, dt, mn in items]
            else:
                out[name] = [_record(z) for z in items]
        self._log = {}
        return out

    def take_measurements(self) -> MeasurementLog:
        """Measurements delivered since the last call, as kept (none of them is changed later):
        per sensor, IMU ``(t, dt, mean)`` fusion intervals, the others their measurements;
        :func:`measurement_row` turns them into a log row."""
        out, self._log = self._log, {}
        return out

    def covariance_row(self) -> list[float]:
        """What :meth:`three_sigma` and :meth:`biases` are made of, as one flat row: the
        covariance diagonal up to the baro bias (16 variances in
        :data:`sim.estimation.ins_model.IDX` order), the
        attitude quaternion (w, x, y, z), the attitude-error covariance block (9, row-major),
        then the biases in :meth:`biases`' order (:data:`sim.log_rows.SIGMA_INPUTS`)."""
        ekf = self.ekf
        nav = ekf.nav
        cov = ekf.kf.P.take(_COVARIANCE_ROW).tolist()  # the diagonal's 16, then the attitude block
        return [*cov[:16], *nav.q, *cov[16:], *nav.ba.tolist(), *nav.bg.tolist(), float(nav.bb), *nav.gm.tolist()]

    def three_sigma(self) -> dict[str, list[float]]:
        """3-sigma bounds of the estimate (see :meth:`InsEkf.three_sigma`), plain floats."""
        cov = self.covariance_row()
        return sigma_bounds(cov[:16], cov[16:20], cov[20:29])

    def biases(self) -> dict[str, list[float]]:
        """Estimated biases: ``accel`` [m/s^2] and ``gyro`` [rad/s] body, ``baro`` height [m],
        ``gnss_gm`` GNSS position error NED [m]."""
        nav = self.ekf.nav
        return {"accel": _floats(nav.ba), "gyro": _floats(nav.bg), "baro": [float(nav.bb)], "gnss_gm": _floats(nav.gm)}


# flat indices into the N x N covariance: its diagonal up to the baro bias, the attitude block
_COVARIANCE_ROW = np.array([k * (N + 1) for k in range(16)] + [r * N + c for r in range(6, 9) for c in range(6, 9)])


def measurement_row(log: MeasurementLog) -> list[float]:
    """Measurements (:meth:`SensorEstimator.take_measurements`) as one flat row, per sensor in
    ``log``'s order, each record ``t`` then its fields in :meth:`SensorEstimator.measurements`'
    order (IMU: ``t``, ``dt``, accel, gyro)."""
    row: list[float] = []
    for name, items in log.items():
        if name == "imu":
            for t, dt, mn in items:
                row += (t, dt, *mn)
        else:
            for z in items:
                row += _values(z)
    return row


def _values(z: Measurement) -> list[float]:
    """A measurement's time and values, flat in :func:`_record`'s order."""
    if type(z) is GnssFix:
        return [z.t, *z.pos_ned.tolist(), *z.vel_ned.tolist()]
    if type(z) is BaroSample:
        return [z.t, float(z.pressure_pa)]
    if type(z) is AirspeedSample:
        return [z.t, float(z.diff_pressure_pa)]
    if type(z) is MagSample:
        return [z.t, *np.asarray(z.field_body_ut, float).tolist()]
    raise TypeError(f"unexpected measurement {z!r}")


def _record(z: Measurement) -> dict[str, Any]:
    if type(z) is GnssFix:
        return {"t": z.t, "pos_ned": _floats(z.pos_ned), "vel_ned": _floats(z.vel_ned)}
    if type(z) is BaroSample:
        return {"t": z.t, "pressure_pa": float(z.pressure_pa)}
    if type(z) is AirspeedSample:
        return {"t": z.t, "diff_pressure_pa": float(z.diff_pressure_pa)}
    if type(z) is MagSample:
        return {"t": z.t, "field_body_ut": _floats(z.field_body_ut)}
    raise TypeError(f"unexpected measurement {z!r}")
