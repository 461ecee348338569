"""ADS-B / cooperative position reports of other aircraft, as received by one vehicle.

Each intruder broadcasts at ``rate_hz`` with its own random phase; a report carries the
intruder's position NED [m] and velocity NED [m/s] at broadcast time with noise (ADS-B altitude
is quantised to 25 ft), is lost with probability ``dropout_probability`` and arrives
``latency_s`` later. Defaults: 2 Hz airborne position (DO-260B), 0.5 s latency, 5 % loss,
3 m N/E and 5 m D position noise (GNSS-sourced, NACp >= 9), 0.5 m/s velocity noise.
Receiver faults (``dropout``, ``stuck``, ``bias_step`` on the 6-vector position+velocity)
apply to every intruder.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping

import numpy as np
from pydantic import Field

from sim.core.state import VehicleState
from sim.sensors.channel import Channel, ChannelConfig
from sim.sensors.config import StrictConfig
from sim.sensors.faults import SensorFault, SensorFaultSchedule
from sim.sensors.measurements import AdsbReport

_EPS = 1e-9


class AdsbConfig(StrictConfig):
    rate_hz: float = Field(2.0, gt=0.0)
    latency_s: float = Field(0.5, ge=0.0)
    dropout_probability: float = Field(0.05, ge=0.0, lt=1.0)
    pos_ne: ChannelConfig = ChannelConfig(noise_std=3.0)
    pos_d: ChannelConfig = ChannelConfig(noise_std=5.0, quantum=7.62)
    vel: ChannelConfig = ChannelConfig(noise_std=0.5)
    cooperative: bool = False


class _Link:
    """One intruder's error channels and report clock; first report at a random phase of the
    ``period`` [s] after first contact at ``t`` [s]."""

    def __init__(self, cfg: AdsbConfig, rng: np.random.Generator, t: float, period: float):
        self.last_t: float | None = None
        self.pos_ne = Channel(cfg.pos_ne, 2, rng)
        self.pos_d = Channel(cfg.pos_d, 1, rng)
        self.vel = Channel(cfg.vel, 3, rng)
        self.next_t = t + period * float(rng.random())


class AdsbReceiver:
    """Reports of any number of intruders, keyed by id; poll once per tick with their truth."""

    name = "adsb"

    def __init__(self, cfg: AdsbConfig, rng: np.random.Generator):
        self.cfg = cfg
        self.rng = rng
        self.faults = SensorFaultSchedule(self.name, 6)
        self._links: dict[str, _Link] = {}
        self._pending: deque[tuple[float, AdsbReport]] = deque()

    def inject(self, fault: SensorFault) -> None:
        self.faults.add(fault)

    def poll(self, t: float, intruders: Mapping[str, VehicleState]) -> list[AdsbReport]:
        """Reports delivered at ``t`` [s]; ``intruders`` maps id -> true state at ``t``."""
        period = 1.0 / self.cfg.rate_hz
        for iid in sorted(intruders):
            link = self._links.get(iid)
            if link is None:
                link = self._links[iid] = _Link(self.cfg, self.rng, t, period)
            if t + _EPS < link.next_t:
                continue
            dt = period if link.last_t is None else t - link.last_t
            link.last_t = t
            link.next_t += period * max(1, math.floor((t + _EPS - link.next_t) / period) + 1)
            s = intruders[iid]
            y = np.concatenate(
                (
                    link.pos_ne.apply(s.pos_ned[:2], dt),
                    link.pos_d.apply(s.pos_ned[2:], dt),
                    link.vel.apply(s.vel_ned, dt),
                )
            )
            lost = self.rng.random() < self.cfg.dropout_probability
            out_y = self.faults.apply(t, y)
            if out_y is None or lost:
                continue
            report = AdsbReport(t, iid, out_y[:3], out_y[3:], self.cfg.cooperative)
            self._pending.append((t + self.cfg.latency_s, report))
        out = []
        while self._pending and self._pending[0][0] <= t + _EPS:
            out.append(self._pending.popleft()[1])
        return out
