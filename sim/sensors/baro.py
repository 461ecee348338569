"""Barometer: static pressure [Pa].

Defaults: white noise 10 Pa (mavsim ``abs_pres_sigma``), turn-on bias 20 Pa, bias random walk
0.05 Pa/sqrt(s), 1.2 Pa LSB (MS5611 at its highest oversampling), 20 Hz, no latency. Note that
a fixed pressure error is a larger altitude error high up (10 Pa = 0.8 m at sea level, 8.5 m at
18 km): :func:`sim.sensors.isa.height_per_pascal`.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from sim.sensors.base import SampledSensor, SensorConfig
from sim.sensors.channel import Channel, ChannelConfig
from sim.sensors.measurements import BaroSample
from sim.sensors.truth import TruthSample


class BaroConfig(SensorConfig):
    rate_hz: float = Field(20.0, gt=0.0)
    pressure: ChannelConfig = ChannelConfig(noise_std=10.0, bias_init_std=20.0, bias_rw=0.05, quantum=1.2)


class Barometer(SampledSensor[BaroSample]):
    """Output vector: static pressure [Pa]."""

    name = "baro"
    dim = 1

    def __init__(self, cfg: BaroConfig, rng: np.random.Generator):
        super().__init__(cfg, rng)
        self.channel = Channel(cfg.pressure, 1, rng)

    def _measure(self, truth: TruthSample, dt: float) -> np.ndarray:
        return self.channel.apply(np.array([truth.static_pressure_pa]), dt)

    def _package(self, t: float, y: np.ndarray) -> BaroSample:
        return BaroSample(t, float(y[0]))
