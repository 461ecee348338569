"""Pitot-static airspeed sensor: differential (dynamic) pressure ``rho TAS^2 / 2`` [Pa].

Defaults: white noise 2 Pa (mavsim ``diff_pres_sigma``), bias random walk 0.01 Pa/sqrt(s),
20 Hz, no latency. Convert to TAS/EAS with :func:`sim.sensors.isa.airspeeds_from_dp` and the
barometer's static pressure.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from sim.sensors.base import SampledSensor, SensorConfig
from sim.sensors.channel import Channel, ChannelConfig
from sim.sensors.measurements import AirspeedSample
from sim.sensors.truth import TruthSample


class AirspeedConfig(SensorConfig):
    rate_hz: float = Field(20.0, gt=0.0)
    diff_pressure: ChannelConfig = ChannelConfig(noise_std=2.0, bias_rw=0.01)


class AirspeedSensor(SampledSensor[AirspeedSample]):
    """Output vector: differential pressure [Pa]."""

    name = "airspeed"
    dim = 1

    def __init__(self, cfg: AirspeedConfig, rng: np.random.Generator):
        super().__init__(cfg, rng)
        self.channel = Channel(cfg.diff_pressure, 1, rng)

    def _measure(self, truth: TruthSample, dt: float) -> np.ndarray:
        return self.channel.apply(np.array([truth.dynamic_pressure_pa]), dt)

    def _package(self, t: float, y: np.ndarray) -> AirspeedSample:
        return AirspeedSample(t, float(y[0]))
