"""GNSS receiver: position local NED [m] and velocity NED [m/s] of the antenna (at the CG).

Position error = first-order Gauss-Markov process (mavsim's GPS model, Beard & McLain ch. 7:
correlation time 1100 s; the stationary std 0.52 m N/E and 1.57 m D equal mavsim's 2017
parameters 0.01 m / 0.03 m per 0.2 s step) + white noise per fix (0.2 m N/E, 0.4 m D) +
quantisation. Velocity: white noise 0.05 m/s N/E (mavsim ``gps_Vg_sigma``), 0.1 m/s D.
5 Hz, 110 ms latency (PX4 ``EKF2_GPS_DELAY`` default). Loss of fix = a ``dropout`` fault.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from sim.sensors.base import SampledSensor, SensorConfig
from sim.sensors.channel import Channel, ChannelConfig
from sim.sensors.measurements import GnssFix
from sim.sensors.truth import TruthSample


class GnssConfig(SensorConfig):
    """Gauss-Markov stationary std [m] and correlation time [s]; white channels per axis group."""

    rate_hz: float = Field(5.0, gt=0.0)
    latency_s: float = Field(0.11, ge=0.0)
    gm_tau_s: float = Field(1100.0, gt=0.0)
    gm_std_ne: float = Field(0.52, ge=0.0)
    gm_std_d: float = Field(1.57, ge=0.0)
    pos_ne: ChannelConfig = ChannelConfig(noise_std=0.2)
    pos_d: ChannelConfig = ChannelConfig(noise_std=0.4)
    vel_ne: ChannelConfig = ChannelConfig(noise_std=0.05)
    vel_d: ChannelConfig = ChannelConfig(noise_std=0.1)


class Gnss(SampledSensor[GnssFix]):
    """Output vector: position N, E, D [m], velocity N, E, D [m/s]."""

    cfg: GnssConfig

    name = "gnss"
    dim = 6

    def __init__(self, cfg: GnssConfig, rng: np.random.Generator):
        super().__init__(cfg, rng)
        self._gm_std = np.array([cfg.gm_std_ne, cfg.gm_std_ne, cfg.gm_std_d])
        self.gm = self._gm_std * rng.standard_normal(3)
        self._pos_ne = Channel(cfg.pos_ne, 2, rng)
        self._pos_d = Channel(cfg.pos_d, 1, rng)
        self._vel_ne = Channel(cfg.vel_ne, 2, rng)
        self._vel_d = Channel(cfg.vel_d, 1, rng)

    def _measure(self, truth: TruthSample, dt: float) -> np.ndarray:
        a = math.exp(-dt / self.cfg.gm_tau_s)
        self.gm = a * self.gm + self._gm_std * math.sqrt(1.0 - a * a) * self.rng.standard_normal(3)
        p = truth.state.pos_ned + self.gm
        v = truth.state.vel_ned
        return np.concatenate(
            (
                self._pos_ne.apply(p[:2], dt),
                self._pos_d.apply(p[2:], dt),
                self._vel_ne.apply(v[:2], dt),
                self._vel_d.apply(v[2:], dt),
            )
        )

    def _package(self, t: float, y: np.ndarray) -> GnssFix:
        return GnssFix(t, y[:3], y[3:])
