"""Fault injection at scenario times: GNSS loss, sensor bias step, stuck sensor, motor failure,
gust. Each start and end is logged as an event.

Sensor faults go to the vehicle's estimator (it must model sensors); motor failures stop a
motor (the airframe's ``ap/motor-health[i]`` goes to 0; JSBSim's ``set-running`` does not stop
electric engines); gusts are JSBSim 1-cosine gusts.
"""

from __future__ import annotations

from sim import scenario as sc
from sim.environment import start_gust
from sim.mcap_log import McapLog


class FaultError(ValueError):
    """A fault the vehicle cannot take (e.g. a sensor fault without sensor models)."""


class FaultSchedule:
    """Starts and ends the scenario's faults; call :meth:`tick` at the log rate."""

    def __init__(self, faults: list, vehicles: dict, log: McapLog):
        self.log = log
        self.vehicles = vehicles
        self._pending = sorted(faults, key=lambda f: f.at)
        self._active: list = []
        for f in self._pending:
            v = vehicles[f.vehicle]
            if isinstance(f, sc.MotorFailure) and f.engine >= v.plant.engine_count:
                raise FaultError(
                    f"fault on {f.vehicle}: engine {f.engine} does not exist ({v.plant.engine_count} engines)"
                )
            if isinstance(f, (sc.GnssLoss, sc.SensorBias, sc.SensorStuck)):
                if not hasattr(v.estimator, "inject"):
                    raise FaultError(
                        f"fault on {f.vehicle}: {f.kind} needs sensor models, but its estimator is {v.estimator.name!r}"
                    )
                v.inject_sensor_fault(f)  # the sensor models switch it on and off at its times

    def _event(self, t: float, f, text: str) -> None:
        self.log.event(t, f"{f.vehicle}: fault {f.kind}: {text}", level="warning", name="faults")

    def tick(self, t: float) -> None:
        while self._pending and self._pending[0].at <= t:
            f = self._pending.pop(0)
            self._start(t, f)
            if f.duration is not None:
                self._active.append(f)
        for f in [f for f in self._active if f.at + f.duration <= t]:
            self._active.remove(f)
            self._end(t, f)

    def _start(self, t: float, f) -> None:
        v = self.vehicles[f.vehicle]
        if isinstance(f, sc.MotorFailure):
            v.plant[f"ap/motor-health[{f.engine}]"] = 0.0
            self._event(t, f, f"engine {f.engine} stopped")
        elif isinstance(f, sc.Gust):
            start_gust(v.plant, f)
            self._event(t, f, f"gust {f.north:.1f}/{f.east:.1f}/{f.down:.1f} m/s NED")
        else:  # already scheduled in the sensor models; logged here
            self._event(t, f, "started" + (f" ({f.sensor})" if hasattr(f, "sensor") else ""))

    def _end(self, t: float, f) -> None:
        if isinstance(f, sc.MotorFailure):
            self.vehicles[f.vehicle].plant[f"ap/motor-health[{f.engine}]"] = 1.0
        self._event(t, f, "ended")
