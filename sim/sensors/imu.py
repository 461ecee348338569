"""Strapdown IMU at the CG: accelerometer (specific force) and gyro (body rates), body FRD.

Defaults are ADIS16448-class as PX4's SITL IMU plugin simulates it (noise densities and bias
random walks are twice the datasheet values there; kept): gyro noise density
3.39e-4 rad/s/sqrt(Hz) (2 x 35/3600 deg/s/sqrt(Hz)), gyro bias random walk 3.88e-5
rad/s^2/sqrt(Hz) (2 x 4/3600 deg/s^2/sqrt(Hz)), turn-on gyro bias 0.5 deg/s; accel noise
density 4e-3 m/s^2/sqrt(Hz), bias random walk 6e-3 m/s^3/sqrt(Hz), turn-on bias 20 mg.
Quantisation: ADIS16448 LSBs (0.04 deg/s, 0.833 mg). Per-sample white noise = density * sqrt(rate).
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field, model_validator

from sim.core.constants import STANDARD_GRAVITY
from sim.sensors.base import SampledSensor, SensorConfig
from sim.sensors.channel import Channel, ChannelConfig
from sim.sensors.measurements import ImuSample
from sim.sensors.truth import TruthSample


class ImuConfig(SensorConfig):
    """Rates in Hz; densities per sqrt(Hz); accel in m/s^2, gyro in rad/s."""

    rate_hz: float = Field(100.0, gt=0.0)
    accel_noise_density: float = Field(4.0e-3, ge=0.0)
    accel_bias_init_std: float = Field(20e-3 * STANDARD_GRAVITY, ge=0.0)
    accel_bias_rw: float = Field(6.0e-3, ge=0.0)
    accel_scale_factor_std: float = Field(0.0, ge=0.0, lt=0.5)
    accel_quantum: float = Field(0.833e-3 * STANDARD_GRAVITY, ge=0.0)
    gyro_noise_density: float = Field(math.radians(2 * 35.0 / 3600.0), ge=0.0)
    gyro_bias_init_std: float = Field(math.radians(0.5), ge=0.0)
    gyro_bias_rw: float = Field(math.radians(2 * 4.0 / 3600.0), ge=0.0)
    gyro_scale_factor_std: float = Field(0.0, ge=0.0, lt=0.5)
    gyro_quantum: float = Field(math.radians(0.04), ge=0.0)

    @model_validator(mode="after")
    def _time_base(self) -> ImuConfig:
        if self.dropout:
            raise ValueError("dropout: the filter is IMU-driven, every IMU sample is used")
        if self.latency_s:
            raise ValueError("latency_s: the IMU is the filter's time base (samples are used at their time)")
        return self

    def accel_channel(self) -> ChannelConfig:
        return ChannelConfig(
            noise_std=self.accel_noise_density * math.sqrt(self.rate_hz),
            bias_init_std=self.accel_bias_init_std,
            bias_rw=self.accel_bias_rw,
            scale_factor_std=self.accel_scale_factor_std,
            quantum=self.accel_quantum,
        )

    def gyro_channel(self) -> ChannelConfig:
        return ChannelConfig(
            noise_std=self.gyro_noise_density * math.sqrt(self.rate_hz),
            bias_init_std=self.gyro_bias_init_std,
            bias_rw=self.gyro_bias_rw,
            scale_factor_std=self.gyro_scale_factor_std,
            quantum=self.gyro_quantum,
        )


class Imu(SampledSensor[ImuSample]):
    """Output vector (faults apply to it): accel x, y, z [m/s^2], gyro x, y, z [rad/s]."""

    name = "imu"
    dim = 6

    def __init__(self, cfg: ImuConfig, rng: np.random.Generator):
        super().__init__(cfg, rng)
        self._accel = Channel(cfg.accel_channel(), 3, rng)
        self._gyro = Channel(cfg.gyro_channel(), 3, rng)
        self._bias_row: int | None = None  # the pool row the channels' biases are still to be set to
        self._blk: tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
        self._walk = self._white = np.empty((0, 6))
        self._rows: tuple[list[list[float]], list[list[float]]] = ([], [])  # the pool as lists
        self._one: tuple[list[float], list[float], list[bool]] = ([], [], [])  # scale, quantum, mask
        self._pool_i = 0

    @property
    def accel(self) -> Channel:
        """The accelerometer channel (its ``bias``: the bias of the newest sample)."""
        self._set_biases()
        return self._accel

    @property
    def gyro(self) -> Channel:
        """The gyro channel (its ``bias``: the bias of the newest sample)."""
        self._set_biases()
        return self._gyro

    def _set_biases(self) -> None:
        """Set the channels' biases to the pool row of the newest sample, if not done yet (the
        per-sample path leaves it to the first reader)."""
        i, self._bias_row = self._bias_row, None
        if i is not None:
            b = self._walk[i]
            self._accel.bias = b[:3].copy()
            self._gyro.bias = b[3:].copy()

    def _measure(self, truth: TruthSample, dt: float) -> np.ndarray:
        return np.concatenate(
            (self.accel.apply(truth.specific_force_body, dt), self.gyro.apply(truth.state.rates_body, dt))
        )

    def _package(self, t: float, y: np.ndarray) -> ImuSample:
        return ImuSample(t, y[:3], y[3:])

    def _take(self, n: int, dt: float) -> int:
        """Reserve ``n`` rows of the noise pool for samples every ``dt`` [s]; the first row's
        index. Sets the channels' biases to the last reserved row's."""
        if self._blk is None or self._blk[0] != dt:
            a, g = self.accel.cfg, self.gyro.cfg
            q = np.array([a.quantum] * 3 + [g.quantum] * 3)
            self._blk = (
                dt,
                np.array([a.bias_rw] * 3 + [g.bias_rw] * 3) * math.sqrt(dt),
                np.array([a.noise_std] * 3 + [g.noise_std] * 3),
                np.where(q > 0.0, q, 1.0),
                q > 0.0,
                np.concatenate((self.accel.scale, self.gyro.scale)),
            )
            self._one = (self._blk[5].tolist(), self._blk[3].tolist(), self._blk[4].tolist())
            self._pool_i = len(self._walk)  # refill with this dt
        i = self._pool_i
        if i + n > len(self._walk):
            m = max(4096, n)
            base = np.concatenate((self.accel.bias, self.gyro.bias))
            self._walk = np.cumsum(self.rng.standard_normal((m, 6)) * self._blk[1], axis=0) + base
            self._white = self.rng.standard_normal((m, 6)) * self._blk[2]
            self._rows = (self._walk.tolist(), self._white.tolist())
            i = 0
        self._pool_i = i + n
        self._bias_row = i + n - 1
        return i

    def measure_one(self, t: float, true: tuple[float, ...], dt: float) -> list[float] | None:
        """One sample of :meth:`measure_block` (the same model and noise pool: the same numbers)
        in plain floats, ``None`` when a fault drops it: the estimator's per-sample path."""
        if self.faults.faults:
            ts, block = self.measure_block(np.array([t]), np.array([true]), dt)
            return block[0].tolist() if len(ts) else None
        i = self._pool_i
        if self._blk is not None and self._blk[0] == dt and i < len(self._rows[0]):  # _take(1, dt), inline
            self._pool_i = i + 1
            self._bias_row = i
        else:
            i = self._take(1, dt)
        scale, quantum, q_mask = self._one
        walk, white = self._rows[0][i], self._rows[1][i]
        return [
            round((x * s + w + e) / q) * q if m else x * s + w + e
            for x, s, w, e, q, m in zip(true, scale, walk, white, quantum, q_mask, strict=True)
        ]

    def measure_block(self, t: np.ndarray, true: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Samples taken at times ``t`` (n,) every ``dt`` [s] from the true specific force and
        rates ``true`` (n, 6: accel x, y, z, gyro x, y, z): the per-sample error model of
        :meth:`poll` (scale, bias random walk per sample, white noise, quantisation) applied to
        the whole block at once (the estimator's fast path). The noise comes from a pool of
        4096 rows drawn from this IMU's generator at a time, pre-scaled, with the bias random
        walk pre-summed (reproducible, but not the same numbers as :meth:`poll`). Faults apply
        per sample; dropped samples are left out. Returns (times (k,), outputs (k, 6))."""
        n = len(t)
        i = self._take(n, dt)
        assert self._blk is not None  # set by _take
        quantum, q_mask, scale = self._blk[3:]
        y = true * scale
        y += self._walk[i : i + n]
        y += self._white[i : i + n]
        if q_mask.all():
            y = np.round(y / quantum) * quantum
        elif q_mask.any():
            y = np.where(q_mask, np.round(y / quantum) * quantum, y)
        if not self.faults.faults:
            return t, y
        keep = []
        for k in range(n):
            yk = self.faults.apply(float(t[k]), y[k])
            if yk is not None:
                y[k] = yk
                keep.append(k)
        return t[keep], y[keep]
