"""``[vehicle.sensors]``: presets and per-sensor tables reach the sensor models; bad values are
field-named errors."""

from __future__ import annotations

import math
import re

import pytest

from sim.estimation.sensor_estimator import SensorEstimatorConfig
from sim.scenario import ScenarioError, SensorsSpec, parse_scenario
from sim.sensors.presets import PRESETS


def _quad(sensors: dict) -> dict:
    return {
        "name": "s",
        "seed": 1,
        "duration": 1.0,
        "origin": {"lat": 47.0, "lon": 8.0, "altitude": 400.0},
        "vehicle": [
            {
                "name": "quad",
                "aircraft": "quadrotor",
                "sensors": sensors,
                "initial": {"altitude": 420.0},
                "mission": {"cruise_speed": 3.0, "waypoints": [{"north": 0, "east": 0, "altitude": 420}]},
            }
        ],
    }


def test_tables_override_the_preset_which_overrides_the_kind_defaults():
    spec = SensorsSpec.model_validate(
        {"preset": "tactical", "imu": {"gyro_bias_rw": 1e-6}, "gnss": {"pos_ne": {"bias_init_std": 2.0}}}
    )
    cfg = spec.estimator_config("multirotor")
    kind = SensorEstimatorConfig.for_kind("multirotor")
    assert cfg.sensors.imu.rate_hz == kind.sensors.imu.rate_hz  # rate: the airframe kind's
    assert cfg.sensors.imu.gyro_noise_density == PRESETS["tactical"]["imu"]["gyro_noise_density"]
    assert cfg.sensors.imu.gyro_noise_density == pytest.approx(math.radians(0.125) / 60.0)
    assert cfg.sensors.imu.gyro_bias_rw == 1e-6  # the table wins over the preset
    assert cfg.sensors.gnss.pos_ne.bias_init_std == 2.0
    assert cfg.sensors.gnss.pos_ne.noise_std == kind.sensors.gnss.pos_ne.noise_std  # nested: merged per key
    assert SensorsSpec().estimator_config("fixed_wing") == SensorEstimatorConfig.for_kind("fixed_wing")


@pytest.mark.parametrize(
    ("sensors", "message"),
    [
        ({"preset": "military"}, "vehicle[0].sensors.preset: Input should be 'consumer' or 'tactical'"),
        ({"gnss": {"dropout": 1.5}}, "vehicle[0].sensors.gnss.dropout: out of range: input should be less than 1"),
        (
            {"baro": {"pressure": {"noise_std": -1}}},
            "vehicle[0].sensors.baro.pressure.noise_std: out of range: input should be greater than or equal to 0",
        ),
        ({"imu": {"gyro_nosie_density": 1e-4}}, "vehicle[0].sensors.imu.gyro_nosie_density: unknown key"),
        ({"imu": {"dropout": 0.1}}, "vehicle[0].sensors.imu: dropout: the filter is IMU-driven"),
        ({"imu": {"latency_s": 0.01}}, "vehicle[0].sensors.imu: latency_s: the IMU is the filter's time base"),
        ({"airspeed": {"rate_hz": 10}}, "vehicle[0]: sensors.airspeed: a multirotor carries no pitot"),
        ({"mag": {"rate_hz": 7}}, "vehicle[0]: sensors: SensorEstimatorConfig: mag.rate_hz: 7 Hz does not divide"),
    ],
)
def test_bad_sensor_tables_are_field_named_errors(sensors, message):
    with pytest.raises(ScenarioError, match=re.escape(message)):
        parse_scenario(_quad(sensors))
