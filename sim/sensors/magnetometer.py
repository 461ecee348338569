"""Three-axis magnetometer: earth field rotated into body FRD [uT].

The earth field is constant over the scenario area, given by total intensity [uT],
inclination (dip, positive down) and declination (east of true north) [rad]; defaults 50 uT,
60 deg, 0 deg (mid-latitude). Errors: white noise 0.1 uT per axis (about 0.2 deg of heading with
25 uT horizontal; mavsim models heading noise directly, 0.03 deg), bias random walk 0.001
uT/sqrt(s), no turn-on bias (hard-iron calibrated), 20 Hz.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from sim.core.frames import euler_to_dcm
from sim.sensors.base import SampledSensor, SensorConfig
from sim.sensors.channel import Channel, ChannelConfig
from sim.sensors.measurements import MagSample
from sim.sensors.truth import TruthSample


class MagnetometerConfig(SensorConfig):
    rate_hz: float = Field(20.0, gt=0.0)
    intensity_ut: float = Field(50.0, gt=0.0)
    inclination_rad: float = Field(math.radians(60.0), ge=-math.pi / 2, le=math.pi / 2)
    declination_rad: float = Field(0.0, ge=-math.pi, le=math.pi)
    field: ChannelConfig = ChannelConfig(noise_std=0.1, bias_rw=0.001)

    def earth_field_ned(self) -> np.ndarray:
        """Earth field in NED [uT]."""
        h = self.intensity_ut * math.cos(self.inclination_rad)
        return np.array(
            [
                h * math.cos(self.declination_rad),
                h * math.sin(self.declination_rad),
                self.intensity_ut * math.sin(self.inclination_rad),
            ]
        )


class Magnetometer(SampledSensor[MagSample]):
    """Output vector: field x, y, z body [uT]."""

    name = "mag"
    dim = 3

    def __init__(self, cfg: MagnetometerConfig, rng: np.random.Generator):
        super().__init__(cfg, rng)
        self._m_ned = cfg.earth_field_ned()
        self.channel = Channel(cfg.field, 3, rng)

    def _measure(self, truth: TruthSample, dt: float) -> np.ndarray:
        r = euler_to_dcm(*truth.state.euler)
        return self.channel.apply(self._m_ned @ r, dt)

    def _package(self, t: float, y: np.ndarray) -> MagSample:
        return MagSample(t, y)
