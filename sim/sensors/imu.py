"""Strapdown IMU at the CG: accelerometer (specific force) and gyro (body rates), body FRD.

Defaults are ADIS16448-class as PX4's SITL IMU plugin simulates it (noise densities and bias
random walks are twice the datasheet values there; kept): gyro noise density
3.39e-4 rad/s/sqrt(Hz) (2 x 35/3600 deg/s/sqrt(Hz)), gyro bias random walk 3.88e-5
rad/s^2/sqrt(Hz) (2 x 4/3600 deg/s^2/sqrt(Hz)), turn-on gyro bias 0.5 deg/s; accel noise density 4e-3 m/s^2/sqrt(Hz), bias random walk 6e-3
m/s^3/sqrt(Hz), turn-on bias 20 mg. Quantisation: ADIS16448 LSBs (0.04 deg/s, 0.833 mg).
Per-sample white noise = density * sqrt(rate).
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from sim.sensors.base import SampledSensor, SensorConfig
from sim.sensors.channel import Channel, ChannelConfig
from sim.sensors.measurements import ImuSample
from sim.sensors.truth import TruthSample

G0 = 9.80665


class ImuConfig(SensorConfig):
    """Rates in Hz; densities per sqrt(Hz); accel in m/s^2, gyro in rad/s."""

    rate_hz: float = Field(100.0, gt=0.0)
    accel_noise_density: float = Field(4.0e-3, ge=0.0)
    accel_bias_init_std: float = Field(20e-3 * G0, ge=0.0)
    accel_bias_rw: float = Field(6.0e-3, ge=0.0)
    accel_scale_factor_std: float = Field(0.0, ge=0.0, lt=0.5)
    accel_quantum: float = Field(0.833e-3 * G0, ge=0.0)
    gyro_noise_density: float = Field(math.radians(2 * 35.0 / 3600.0), ge=0.0)
    gyro_bias_init_std: float = Field(math.radians(0.5), ge=0.0)
    gyro_bias_rw: float = Field(math.radians(2 * 4.0 / 3600.0), ge=0.0)
    gyro_scale_factor_std: float = Field(0.0, ge=0.0, lt=0.5)
    gyro_quantum: float = Field(math.radians(0.04), ge=0.0)

    def accel_channel(self) -> ChannelConfig:
        return ChannelConfig(noise_std=self.accel_noise_density * math.sqrt(self.rate_hz),
                             bias_init_std=self.accel_bias_init_std, bias_rw=self.accel_bias_rw,
                             scale_factor_std=self.accel_scale_factor_std, quantum=self.accel_quantum)

    def gyro_channel(self) -> ChannelConfig:
        return ChannelConfig(noise_std=self.gyro_noise_density * math.sqrt(self.rate_hz),
                             bias_init_std=self.gyro_bias_init_std, bias_rw=self.gyro_bias_rw,
                             scale_factor_std=self.gyro_scale_factor_std, quantum=self.gyro_quantum)


class Imu(SampledSensor[ImuSample]):
    """Output vector (faults apply to it): accel x, y, z [m/s^2], gyro x, y, z [rad/s]."""

    name = "imu"
    dim = 6

    def __init__(self, cfg: ImuConfig, rng: np.random.Generator):
        super().__init__(cfg, rng)
        self.accel = Channel(cfg.accel_channel(), 3, rng)
        self.gyro = Channel(cfg.gyro_channel(), 3, rng)
        self._blk = None
        self._pool = np.empty((0, 12))
        self._pool_i = 0

    def _measure(self, truth: TruthSample, dt: float) -> np.ndarray:
        return np.concatenate((self.accel.apply(truth.specific_force_body, dt),
                               self.gyro.apply(truth.state.rates_body, dt)))

    def _package(self, t: float, y: np.ndarray) -> ImuSample:
        return ImuSample(t, y[:3], y[3:])

    def measure_block(self, t: np.ndarray, accel_true: np.ndarray, gyro_true: np.ndarray,
                      dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Samples taken at times ``t`` (n,) every ``dt`` [s] from the true specific force and
        rates (n, 3) each: the per-sample error model of :meth:`poll` (scale, bias random walk
        per sample, white noise, quantisation) applied to the whole block in a few vectorised
        operations on all six axes (the estimator's fast path). The standard normals come from
        a pool refilled from this IMU's generator 4096 rows at a time (reproducible, but not the
        same numbers as :meth:`poll`). Faults apply per sample; dropped samples are left out.
        Returns (times (k,), outputs (k, 6): accel, gyro)."""
        n = len(t)
        if self._blk is None or self._blk[0] != dt:
            a, g = self.accel.cfg, self.gyro.cfg
            q = np.array([a.quantum] * 3 + [g.quantum] * 3)
            self._blk = (dt, np.array([a.bias_rw] * 3 + [g.bias_rw] * 3) * math.sqrt(dt),
                         np.array([a.noise_std] * 3 + [g.noise_std] * 3), np.where(q > 0.0, q, 1.0),
                         bool((q > 0.0).all()), q > 0.0, np.concatenate((self.accel.scale, self.gyro.scale)))
        _, rw, noise, quantum, q_all, q_mask, scale = self._blk
        if self._pool_i + n > len(self._pool):
            self._pool = self.rng.standard_normal((max(4096, n), 12))
            self._pool_i = 0
        z = self._pool[self._pool_i:self._pool_i + n]
        self._pool_i += n
        b = np.cumsum(z[:, :6] * rw, axis=0)
        b += np.concatenate((self.accel.bias, self.gyro.bias))
        self.accel.bias = b[-1, :3].copy()
        self.gyro.bias = b[-1, 3:].copy()
        y = np.concatenate((accel_true, gyro_true), axis=1)
        y *= scale
        y += b
        y += z[:, 6:] * noise
        if q_all:
            y = np.round(y / quantum) * quantum
        elif q_mask.any():
            y = np.where(q_mask, np.round(y / quantum) * quantum, y)
        if not self.faults.faults:
            return t, y
        keep = []
        for i in range(n):
            yi = self.faults.apply(float(t[i]), y[i])
            if yi is not None:
                y[i] = yi
                keep.append(i)
        return t[keep], y[keep]
