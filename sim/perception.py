"""What one vehicle senses of the traffic around it: position reports of the other vehicles
and objects (ADS-B for cooperative ones, a surveillance sensor with the same error model for the
rest) fused by constant-velocity Kalman tracks into ``IntruderTrack``s (local-level NED [m],
covariances [m^2]). Reports are drawn from the traffic's true states (a sensor may read truth;
what it hands on is noisy, late and sometimes missing).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from sim import scenario as sc
from sim.core.state import VehicleState
from sim.core.threats import IntruderTrack
from sim.estimation.intruder_tracker import IntruderTracker, TrackerConfig
from sim.sensors.adsb import AdsbConfig, AdsbReceiver
from sim.sensors.channel import ChannelConfig


class Perception:
    def __init__(self, cfg: sc.Surveillance, rng: np.random.Generator):
        receiver = AdsbConfig(
            rate_hz=cfg.rate_hz,
            latency_s=cfg.latency,
            dropout_probability=cfg.dropout,
            pos_ne=ChannelConfig(noise_std=cfg.position_noise_horizontal),
            pos_d=ChannelConfig(noise_std=cfg.position_noise_vertical),
            vel=ChannelConfig(noise_std=cfg.velocity_noise),
        )
        self.receiver = AdsbReceiver(receiver, rng)
        self.tracker = IntruderTracker(
            TrackerConfig(
                pos_std_ne=max(cfg.position_noise_horizontal, 1e-3),
                pos_std_d=max(cfg.position_noise_vertical, 1e-3),
                vel_std=max(cfg.velocity_noise, 1e-3),
            )
        )
        self._targets: dict[str, tuple[float, bool]] = {}

    def update(self, t: float, traffic: dict[str, tuple[VehicleState, float, bool]]) -> list[IntruderTrack]:
        """Sense ``traffic`` (id -> (true state, body radius [m], cooperative)) at ``t`` [s];
        returns the current tracks."""
        self._targets.update({k: (r, c) for k, (_, r, c) in traffic.items()})
        self.tracker.push(self.receiver.poll(t, {k: s for k, (s, _, _) in traffic.items()}))
        return [
            dataclasses.replace(tr, radius_m=self._targets[tr.id][0], cooperative=self._targets[tr.id][1])
            for tr in self.tracker.tracks(t)
        ]
