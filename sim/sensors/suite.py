"""The sensor set of one vehicle: IMU, GNSS, barometer, airspeed, magnetometer.

Each sensor draws from its own child generator spawned from the vehicle's generator in a fixed
order, so enabling or reconfiguring one sensor does not change the others' noise. A sensor
whose config is ``None`` is absent.
"""

from __future__ import annotations

import numpy as np

from sim.sensors.airspeed import AirspeedConfig, AirspeedSensor
from sim.sensors.baro import BaroConfig, Barometer
from sim.sensors.base import SampledSensor
from sim.sensors.config import SensorConfigError, StrictConfig
from sim.sensors.faults import SensorFault
from sim.sensors.gnss import Gnss, GnssConfig
from sim.sensors.imu import Imu, ImuConfig
from sim.sensors.magnetometer import Magnetometer, MagnetometerConfig
from sim.sensors.measurements import Measurement
from sim.sensors.truth import TruthSample


class SensorSuiteConfig(StrictConfig):
    imu: ImuConfig | None = ImuConfig()
    gnss: GnssConfig | None = GnssConfig()
    baro: BaroConfig | None = BaroConfig()
    airspeed: AirspeedConfig | None = AirspeedConfig()
    mag: MagnetometerConfig | None = MagnetometerConfig()


_KINDS = (("imu", Imu), ("gnss", Gnss), ("baro", Barometer), ("airspeed", AirspeedSensor), ("mag", Magnetometer))


class SensorSuite:
    def __init__(self, cfg: SensorSuiteConfig, rng: np.random.Generator):
        self.cfg = cfg
        children = rng.spawn(len(_KINDS))
        self.sensors: dict[str, SampledSensor] = {
            name: cls(getattr(cfg, name), child)
            for (name, cls), child in zip(_KINDS, children, strict=False)
            if getattr(cfg, name) is not None
        }

    def inject(self, sensor: str, fault: SensorFault) -> None:
        """Schedule ``fault`` on sensor ``sensor`` (``imu``, ``gnss``, ``baro``, ...)."""
        if sensor not in self.sensors:
            raise SensorConfigError(f"no sensor {sensor!r} (have {', '.join(self.sensors)})")
        self.sensors[sensor].inject(fault)

    def poll(self, truth: TruthSample) -> list[Measurement]:
        """Measurements delivered at ``truth.t``, IMU first."""
        out: list[Measurement] = []
        for s in self.sensors.values():
            out.extend(s.poll(truth))
        return out
