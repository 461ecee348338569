"""INS/GNSS error-state EKF of one vehicle (filterpy ``ExtendedKalmanFilter``): IMU-driven
prediction; GNSS position+velocity, barometric height and magnetometer updates;
accelerometer, gyro and baro biases and the GNSS Gauss-Markov position error as states.

The magnetometer is fused as a 3-axis vector against the known earth field (``H = [m_body]x``),
which carries the heading information exactly; a tilt-compensated heading computed with the
*estimated* roll/pitch has an error correlated with the tilt error (x tan(inclination)) that
the filter cannot see, and made it overconfident in hover (tested: 51 % inside 3 sigma).

filterpy's EKF holds the 19-element *error* state (always zero between steps) and its covariance:
``predict()`` with our analytic transition ``F`` and discrete ``Q``; ``update()`` with each
measurement's own ``H``, ``R`` and residual (multi-rate fusion works because ``R`` is passed per
call). After an update the error is injected into the nominal state (``ins_model.NavState``:
quaternion attitude) and reset to zero. The model and Jacobians are in
:mod:`sim.estimation.ins_model`.

Hand-over from the world, per tick::

    ekf.push(sensor_suite.poll(truth_sample))   # measurements delivered this tick, any order
    estimate = ekf.update(t)                     # Estimator protocol: fuses them, returns state

IMU samples are integrated in order (trapezoidal: each step uses the mean of its two end
samples). An aiding measurement is fused when it is handed over; its latency (filter time minus
its time of validity) is compensated by back-shifting the prediction to the time of validity to
first order (``p - v lag``, ``v - a lag``) — cheaper than PX4's delayed fusion horizon, exact
enough for the 0.1–0.2 s GNSS delays here.

Frames: velocity and attitude are local NED at the vehicle, position is scenario coordinates
(tangent plane at the origin); position moves with ``C v``, ``C`` from
:meth:`LocalGeodetic.velocity_map` at the current estimate (recomputed every
``_C_REFRESH_M`` of travel), in the prediction, the GNSS lag term and the output
extrapolation (see :mod:`sim.estimation.ins_model`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Literal

import numpy as np
from pydantic import Field

from sim.core.constants import STANDARD_GRAVITY
from sim.core.frames import (
    euler_to_quat,
    quat_exp,
    quat_mul,
    quat_normalize,
    quat_to_dcm,
    quat_to_euler,
)
from sim.core.state import VehicleState
from sim.estimation import ins_model as m
from sim.estimation.geodetic import LocalGeodetic
from sim.geodesy import GeoPoint
from sim.sensors import isa
from sim.sensors.config import StrictConfig
from sim.sensors.measurements import AirspeedSample, BaroSample, GnssFix, ImuSample, MagSample
from sim.sensors.suite import SensorSuiteConfig

_DIAGONAL = [k * (m.N + 1) for k in range(16)]  # flat indices of the covariance diagonal's first 16
_POS_DIAGONAL = _DIAGONAL[0:3]  # those of the position error's variances, N, E, D [m^2]
_ROWS = {GnssFix: 6, BaroSample: 1, MagSample: 3}  # rows each measurement adds to a stacked update
_C_REFRESH_M = 10.0  # recompute the velocity map after this much travel [m] (C changes ~2e-6/10 m)


class InsEkfConfig(StrictConfig):
    """Noise model of the filter (defaults match the default sensors) and initial uncertainty.
    Units: densities per sqrt(Hz); std in the measured unit; angles rad."""

    accel_noise_density: float = Field(4.0e-3, gt=0.0)
    gyro_noise_density: float = Field(3.39e-4, gt=0.0)
    accel_bias_rw: float = Field(6.0e-3, ge=0.0)
    gyro_bias_rw: float = Field(3.88e-5, ge=0.0)
    baro_bias_rw_m: float = Field(0.05, ge=0.0)
    gnss_gm_tau_s: float = Field(1100.0, gt=0.0)
    gnss_gm_std_ne: float = Field(0.52, ge=0.0)
    gnss_gm_std_d: float = Field(1.57, ge=0.0)
    gnss_pos_std_ne: float = Field(0.2, gt=0.0)
    gnss_pos_std_d: float = Field(0.4, gt=0.0)
    gnss_vel_std_ne: float = Field(0.05, gt=0.0)
    gnss_vel_std_d: float = Field(0.1, gt=0.0)
    baro_noise_pa: float = Field(10.0, gt=0.0)
    mag_noise_ut: float = Field(0.15, gt=0.0)
    mag_intensity_ut: float = Field(50.0, gt=0.0)
    mag_inclination_rad: float = Field(math.radians(60.0), ge=-math.pi / 2, le=math.pi / 2)
    mag_declination_rad: float = Field(0.0, ge=-math.pi, le=math.pi)
    init_pos_std_m: float = Field(3.0, gt=0.0)
    init_vel_std_mps: float = Field(0.5, gt=0.0)
    init_tilt_std_rad: float = Field(math.radians(2.0), gt=0.0)
    init_yaw_std_rad: float = Field(math.radians(5.0), gt=0.0)
    init_accel_bias_std: float = Field(0.2, gt=0.0)
    init_gyro_bias_std: float = Field(math.radians(0.5), gt=0.0)
    init_baro_bias_std_m: float = Field(30.0, gt=0.0)
    gravity_mps2: float = Field(STANDARD_GRAVITY, gt=9.7, lt=9.9)
    jacobians: Literal["analytic", "numeric"] = "analytic"

    @classmethod
    def matching(cls, sensors: SensorSuiteConfig, **overrides) -> InsEkfConfig:
        """Filter noise taken from the sensor configs (what a well-tuned filter would assume)."""
        f: dict = {}
        if (i := sensors.imu) is not None:
            f |= {
                "accel_noise_density": i.accel_noise_density,
                "gyro_noise_density": i.gyro_noise_density,
                "accel_bias_rw": i.accel_bias_rw,
                "gyro_bias_rw": i.gyro_bias_rw,
                "init_accel_bias_std": max(i.accel_bias_init_std, 1e-3),
                "init_gyro_bias_std": max(i.gyro_bias_init_std, 1e-4),
            }
        if (g := sensors.gnss) is not None:
            f |= {
                "gnss_gm_tau_s": g.gm_tau_s,
                "gnss_gm_std_ne": g.gm_std_ne,
                "gnss_gm_std_d": g.gm_std_d,
                "gnss_pos_std_ne": _white(g.pos_ne),
                "gnss_pos_std_d": _white(g.pos_d),
                "gnss_vel_std_ne": _white(g.vel_ne),
                "gnss_vel_std_d": _white(g.vel_d),
            }
        if (b := sensors.baro) is not None:
            f |= {"baro_noise_pa": _white(b.pressure)}
        if (mg := sensors.mag) is not None:
            f |= {
                "mag_noise_ut": 1.5 * _white(mg.field),
                "mag_intensity_ut": mg.intensity_ut,
                "mag_inclination_rad": mg.inclination_rad,
                "mag_declination_rad": mg.declination_rad,
            }
        return cls.build(**(f | overrides))


def _white(ch) -> float:
    """Per-sample white std of a channel including its quantisation noise (floor 1e-6)."""
    return max(math.sqrt(ch.noise_std**2 + ch.quantum**2 / 12.0), 1e-6)


class InsEkf:
    """Implements :class:`sim.estimator.Estimator`. ``initial`` is the prior state (e.g. the
    scenario's initial conditions); ``origin`` the scenario origin (for lat/lon and the baro
    height reference)."""

    name = "ins_ekf"

    def __init__(self, cfg: InsEkfConfig, initial: VehicleState, origin: GeoPoint):
        self.cfg = cfg
        self.origin = origin
        self._geo = LocalGeodetic(origin)
        c = cfg
        self.nav = m.NavState(
            np.array(initial.pos_ned, float),
            np.array(initial.vel_ned, float),
            euler_to_quat(*initial.euler),
            np.zeros(3),
            np.zeros(3),
            0.0,
            np.zeros(3),
        )
        # filterpy (and the scipy.stats it loads, ~0.8 s) is imported by the filter, not by the
        # module: scenario validation imports this module's configuration only.
        from filterpy.kalman import ExtendedKalmanFilter

        kf = self.kf = ExtendedKalmanFilter(dim_x=m.N, dim_z=1)
        kf.x = np.zeros(m.N)
        kf.P = np.diag(
            np.concatenate(
                (
                    [c.init_pos_std_m] * 3,
                    [c.init_vel_std_mps] * 3,
                    [c.init_tilt_std_rad] * 2,
                    [c.init_yaw_std_rad],
                    [c.init_accel_bias_std] * 3,
                    [c.init_gyro_bias_std] * 3,
                    [c.init_baro_bias_std_m],
                    [c.gnss_gm_std_ne] * 2,
                    [c.gnss_gm_std_d],
                )
            )
            ** 2
        )
        kf.P[6:9, 6:9] = self._tilt_yaw_to_body(kf.P[6:9, 6:9], self.nav.q)
        self._q_rates = np.concatenate(
            (
                [0.0] * 3,
                [c.accel_noise_density**2] * 3,
                [c.gyro_noise_density**2] * 3,
                [c.accel_bias_rw**2] * 3,
                [c.gyro_bias_rw**2] * 3,
                [c.baro_bias_rw_m**2],
                [0.0] * 3,
            )
        )
        self._gm_var = np.array([c.gnss_gm_std_ne, c.gnss_gm_std_ne, c.gnss_gm_std_d]) ** 2
        self._phi = np.eye(m.N)
        self._H_gnss = np.zeros((6, m.N))
        self._H_gnss[0:3, 0:3] = self._H_gnss[0:3, 16:19] = self._H_gnss[3:6, 3:6] = np.eye(3)
        self._R_gnss = (
            np.diag(
                [
                    c.gnss_pos_std_ne,
                    c.gnss_pos_std_ne,
                    c.gnss_pos_std_d,
                    c.gnss_vel_std_ne,
                    c.gnss_vel_std_ne,
                    c.gnss_vel_std_d,
                ]
            )
            ** 2
        )
        self._H_baro = np.zeros((1, m.N))
        self._H_baro[0, 2], self._H_baro[0, 15] = -1.0, 1.0
        self._H_mag = np.zeros((3, m.N))
        self._R_mag = np.eye(3) * c.mag_noise_ut**2
        self._R_gnss_diag = np.diag(self._R_gnss).tolist()
        self._R_mag_diag = np.diag(self._R_mag).tolist()
        hm = c.mag_intensity_ut * math.cos(c.mag_inclination_rad)
        self._field_ned = [  # the earth field NED [uT]
            hm * math.cos(c.mag_declination_rad),
            hm * math.sin(c.mag_declination_rad),
            c.mag_intensity_ut * math.sin(c.mag_inclination_rad),
        ]
        self._numeric = c.jacobians == "numeric"
        self._gravity = [0.0, 0.0, c.gravity_mps2]  # NED [m/s^2]
        self._inbox: list = []
        self._imu: ImuSample | None = None
        self._acc_ned = [0.0, 0.0, 0.0]  # the latest prediction's NED acceleration [m/s^2]
        self._rates = np.array(initial.rates_body, float)
        self.t = initial.t
        self._c_at = (math.inf, math.inf, math.inf)
        self._c = np.eye(3)
        self._c9 = m.mat3(self._c)  # the same as plain floats, for the mechanisation
        self._refresh_c()
        self._q_dt = math.nan  # the step [s] of the two below (:meth:`_process_noise`)
        self._decay = 1.0
        self._Q = np.zeros((m.N, m.N))
        self._p_static: float | None = None
        self._dp: float | None = None

    @staticmethod
    def _tilt_yaw_to_body(p_ned: np.ndarray, q) -> np.ndarray:
        """Covariance of a NED-frame attitude error (tilt N, E, yaw) as a body-frame error."""
        r = quat_to_dcm(q)
        return r.T @ p_ned @ r

    def velocity_map(self) -> np.ndarray:
        """``C`` (local-NED velocity -> rate of the scenario coordinates) near the current
        position estimate: refreshed by the predictions once the estimate has moved
        ``_C_REFRESH_M`` (C changes by ~2e-6 per 10 m)."""
        return self._c

    def _refresh_c(self) -> np.ndarray:
        x, y, z = self.nav.p.tolist()
        a = self._c_at
        if abs(x - a[0]) + abs(y - a[1]) + abs(z - a[2]) > _C_REFRESH_M:
            self._c = self._geo.velocity_map(x, y, z)
            self._c9 = m.mat3(self._c)
            self._c_at = (x, y, z)
        return self._c

    # -- Estimator protocol ---------------------------------------------------------------------
    def push(self, measurements: Iterable) -> None:
        """Queue measurements delivered since the last :meth:`update` (fused there, in order)."""
        self._inbox.extend(measurements)

    def update(self, t: float) -> VehicleState:
        """Fuse the queued measurements and return the estimate at ``t`` [s]."""
        for z in self._inbox:
            if type(z) is ImuSample:
                self.predict(z)
            elif type(z) is GnssFix:
                self.fuse_gnss(z)
            elif type(z) is BaroSample:
                self.fuse_baro(z)
            elif type(z) is MagSample:
                self.fuse_mag(z)
            elif type(z) is AirspeedSample:
                self._dp = z.diff_pressure_pa
        self._inbox.clear()
        return self.state(t)

    # -- prediction -----------------------------------------------------------------------------
    def predict(self, z: ImuSample) -> None:
        prev, self._imu = self._imu, z
        if prev is None:
            return
        dt = z.t - prev.t
        if dt <= 0.0:
            return
        f = 0.5 * (prev.accel_body + z.accel_body)
        w = 0.5 * (prev.gyro_body + z.gyro_body)
        decay, q = self._process_noise(dt)
        c = self._refresh_c()
        if self._numeric:
            phi = m.transition_numeric(self.nav, f, w, dt, decay, c_pos=c)
        nav, r, fh, wh = m.propagate(self.nav, f, w, dt, decay, self._gravity, self._c9)
        if not self._numeric:
            phi = m.transition_analytic(self._phi, r, fh, wh, dt, decay, self._c9)
        self._acc_ned = self._acceleration(r, fh)
        self._rates = z.gyro_body - nav.bg
        self.kf.F = phi
        self.kf.Q = q
        self.kf.predict()
        self.nav = nav
        self.t = z.t

    def _acceleration(self, r: m.Mat3, fh: m.Vec3) -> m.Vec3:
        """NED acceleration [m/s^2]: the rotated bias-corrected specific force plus gravity."""
        ax, ay, az = m.rotate(r, fh)
        gx, gy, gz = self._gravity
        return [ax + gx, ay + gy, az + gz]

    def _process_noise(self, dt: float) -> tuple[float, np.ndarray]:
        """The Gauss-Markov decay over a step of ``dt`` [s] and the step's discrete process
        noise Q (19x19, diagonal), worked out again only when the step changes."""
        if dt != self._q_dt:
            decay = math.exp(-dt / self.cfg.gnss_gm_tau_s)
            qd = self._q_rates * dt
            qd[16:19] = self._gm_var * (1.0 - decay * decay)
            self._q_dt, self._decay, self._Q = dt, decay, np.diag(qd)
        return self._decay, self._Q

    # -- updates --------------------------------------------------------------------------------
    def _fuse(self, z: np.ndarray, hx: np.ndarray, H: np.ndarray, R: np.ndarray) -> None:
        kf = self.kf
        kf.update(z, lambda _x: H, lambda _x: hx, R=R)
        self.nav = m.boxplus(self.nav, kf.x)
        kf.x = np.zeros(m.N)

    def fuse_gnss(self, z: GnssFix) -> None:
        lag = self.t - z.t
        c = self._c
        h = lambda s: m.h_gnss(s, lag, self._acc_ned, c)  # noqa: E731
        H = m.jacobian_numeric(h, self.nav) if self._numeric else m.H_gnss(self._H_gnss, lag, c)
        self._fuse(np.concatenate((z.pos_ned, z.vel_ned)), h(self.nav), H, self._R_gnss)

    def fuse_baro(self, z: BaroSample) -> None:
        p = z.pressure_pa
        self._p_static = p
        height = isa.altitude_of_pressure(p) - self.origin.alt_m
        std = self.cfg.baro_noise_pa * isa.height_per_pascal(p)
        H = m.jacobian_numeric(m.h_baro, self.nav) if self._numeric else self._H_baro
        self._fuse(np.array([height]), m.h_baro(self.nav), H, np.array([[std * std]]))

    def fuse_mag(self, z: MagSample) -> None:
        h = lambda s: m.h_mag(s, self._field_ned)  # noqa: E731
        hx = h(self.nav)
        H = m.jacobian_numeric(h, self.nav) if self._numeric else m.H_mag(self._H_mag, hx)
        self._fuse(z.field_body_ut, hx, H, self._R_mag)

    # -- fast paths (sim.estimation.sensor_estimator): one predict per fusion interval from the
    # IMU samples averaged over it, and one stacked update per interval, without filterpy ------
    def predict_mean(self, f: m.Vector3, w: m.Vector3, dt: float, t_end: float, w_last: m.Vector3) -> None:
        """Propagate over ``dt`` [s] to ``t_end`` with the specific force ``f`` and rate ``w``
        averaged over the interval (trapezoid over its IMU samples); ``w_last`` is the newest
        gyro sample (the output body rate). ``P <- Phi P Phi^T + Q`` in place of filterpy."""
        if dt <= 0.0:
            return
        decay, q = self._process_noise(dt)
        self._refresh_c()
        nav, r, fh, wh = m.propagate(self.nav, f, w, dt, decay, self._gravity, self._c9)
        phi = m.transition_analytic(self._phi, r, fh, wh, dt, decay, self._c9)
        self._acc_ned = self._acceleration(r, fh)
        self._rates = np.subtract(w_last, nav.bg)
        P = phi @ self.kf.P @ phi.T
        P += q
        self.kf.P = P
        self.nav = nav
        self.t = t_end

    def fuse_batch(self, measurements: Iterable) -> int:
        """Fuse aiding measurements (GNSS, baro, magnetometer; airspeed is stored) in ONE
        stacked Kalman update linearised at the current state (they are independent given the
        state, so this equals sequential updates to first order). Each is back-shifted by its
        lag (filter time - time of validity): GNSS as in :meth:`fuse_gnss`, baro height by
        ``v_D lag``. Returns the number of rows fused."""
        zs = list(measurements)
        n = sum(_ROWS.get(type(z), 0) for z in zs)
        H = np.zeros((n, m.N))  # the stacked Jacobian, filled block by block
        z: list[float] = []  # measured values
        h: list[float] = []  # their predictions
        r: list[float] = []  # their noise variances
        nav = self.nav
        for meas in zs:
            tz, k = type(meas), len(z)
            if tz is GnssFix:
                lag = self.t - meas.t
                z += meas.pos_ned.tolist()
                z += meas.vel_ned.tolist()
                h += m.gnss_prediction(nav, lag, self._acc_ned, self._c9)
                H[k : k + 6] = self._H_gnss
                m.H_gnss(H[k : k + 6], lag, self._c)
                r += self._R_gnss_diag
            elif tz is BaroSample:
                p = meas.pressure_pa
                self._p_static = p
                lag = self.t - meas.t
                std = self.cfg.baro_noise_pa * isa.height_per_pascal(p)
                z.append(isa.altitude_of_pressure(p) - self.origin.alt_m)
                h.append(-(float(nav.p[2]) - float(nav.v[2]) * lag) + nav.bb)
                H[k] = self._H_baro[0]
                H[k, 5] = lag
                r.append(std * std)
            elif tz is MagSample:
                hx = m.mag_prediction(nav.q, self._field_ned)
                z += np.asarray(meas.field_body_ut, float).tolist()
                h += hx
                m.H_mag(H[k : k + 3], hx)
                r += self._R_mag_diag
            elif tz is AirspeedSample:
                self._dp = meas.diff_pressure_pa
        if not n:
            return 0
        y = np.array([a - b for a, b in zip(z, h, strict=True)])
        P = self.kf.P
        PHt = P @ H.T
        S = H @ PHt
        S.flat[:: n + 1] += r
        K = PHt @ np.linalg.inv(S)
        P = P - K @ PHt.T
        self.kf.P = 0.5 * (P + P.T)
        dx = K @ y
        nav.p += dx[0:3]  # inject the error in place (the fast path owns its arrays)
        nav.v += dx[3:6]
        nav.q = quat_normalize(quat_mul(nav.q, quat_exp(*dx[6:9].tolist())))
        nav.ba += dx[9:12]
        nav.bg += dx[12:15]
        nav.bb += float(dx[15])
        nav.gm += dx[16:19]
        return n

    # -- outputs --------------------------------------------------------------------------------
    @property
    def covariance(self) -> np.ndarray:
        """Error-state covariance (19x19), order of ``ins_model.IDX``."""
        return self.kf.P

    def three_sigma(self) -> dict[str, np.ndarray]:
        """3-sigma bounds (:func:`sim.estimation.ins_model.sigma_bounds`: ``pos``, ``vel``,
        ``att``, ``heading``, ``accel``, ``gyro``, ``baro``) as arrays."""
        P = self.kf.P
        var = P.take(_DIAGONAL).tolist()
        bounds = m.sigma_bounds(var, self.nav.q, P[6:9, 6:9].ravel().tolist())
        return {k: np.asarray(v) for k, v in bounds.items()}

    def state(self, t: float) -> VehicleState:
        """Estimate extrapolated from the filter time to ``t`` [s] (constant velocity, moving the
        scenario position along ``C v``)."""
        nav = self.nav
        pos = nav.p.tolist()
        v = nav.v.tolist()
        if t != self.t:
            dt = t - self.t
            cv = m.rotate(self._c9, v)
            pos = [pos[0] + cv[0] * dt, pos[1] + cv[1] * dt, pos[2] + cv[2] * dt]
        lat, lon, alt = self._geo.ned_to_geodetic(*pos)
        if self._dp is not None and self._p_static is not None:
            tas, eas = isa.airspeeds_from_dp(self._dp, self._p_static)
        else:  # no pitot: ground speed, air density from the ISA at the estimated altitude
            tas = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
            eas = tas * math.sqrt(isa.pressure_at_altitude(alt) / isa.P0 * isa.T0 / isa.temperature_at_altitude(alt))
        return VehicleState(
            t=t,
            pos_ned=np.array(pos),
            vel_ned=np.array(v),
            euler=np.array(quat_to_euler(nav.q)),
            rates_body=self._rates.copy(),
            alt_msl_m=alt,
            lat_deg=lat,
            lon_deg=lon,
            tas_mps=tas,
            eas_mps=eas,
            pos_sigma_m=np.sqrt(np.maximum(self.kf.P.take(_POS_DIAGONAL), 0.0)),
        )
