"""Sensor quality presets for ``[vehicle.sensors] preset`` (error parameters only; the rates
come from the airframe kind, ``SensorEstimatorConfig.for_kind``).

- ``consumer``: the sensor models' own defaults (IMU: ADIS16448-class as PX4's SITL simulates
  it, ``sim/sensors/imu.py``; GNSS, baro, pitot, magnetometer: their modules' defaults).
- ``tactical``: a Honeywell HG1700-class IMU, 1-sigma values of its brochure as quoted by
  NavToolkit's ``hg1700_model`` (https://is4s.github.io/NavToolkit/): gyro bias 1 deg/h, angle
  random walk 0.125 deg/sqrt(h), accelerometer bias 1 mg, velocity random walk 0.065
  ft/s/sqrt(h). The in-run bias random walks are not on the brochure: set to 1 % of the
  consumer values (assumed). Quantisation and the aiding sensors as ``consumer``.
"""

from __future__ import annotations

import math

from sim.core.constants import FT, STANDARD_GRAVITY
from sim.sensors.imu import ImuConfig

_CONSUMER_IMU = ImuConfig()

# sensor -> field -> value (units of the sensor configs: SI, densities per sqrt(Hz))
PRESETS: dict[str, dict[str, dict[str, float]]] = {
    "consumer": {},
    "tactical": {
        "imu": {
            "gyro_noise_density": math.radians(0.125) / 60.0,
            "gyro_bias_init_std": math.radians(1.0) / 3600.0,
            "gyro_bias_rw": 0.01 * _CONSUMER_IMU.gyro_bias_rw,
            "accel_noise_density": 0.065 * FT / 60.0,
            "accel_bias_init_std": 1e-3 * STANDARD_GRAVITY,
            "accel_bias_rw": 0.01 * _CONSUMER_IMU.accel_bias_rw,
        }
    },
}
