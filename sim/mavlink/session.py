"""MAVLink during a run: one :class:`VehicleLink` per vehicle, telemetry out, commands in.

Called by the runner at the log rate (after the vehicles' logging, so a GCS sees the tick's
estimates). Commands a ground station sends are applied to the vehicle they address (see
:meth:`sim.vehicle.Vehicle.apply_command`) and each is logged as an event. With ``pace`` > 0
the run is slowed to at most ``pace`` times the wall clock, so that a person at a GCS can
follow it; 0 runs in sim time, as fast as the simulation goes.
"""

from __future__ import annotations

from sim.geodesy import GeoPoint, ned_to_geodetic
from sim.mavlink.bridge import LinkConfig, VehicleLink
from sim.mavlink.pacing import WallClockPacer
from sim.mcap_log import McapLog


class MavlinkSession:
    def __init__(self, cfg, vehicles: list, origin: GeoPoint, log: McapLog):
        self.vehicles = vehicles
        self.origin = origin
        self.log = log
        self.pacer = WallClockPacer(cfg.pace) if cfg.pace > 0 else None
        self._t = 0.0
        self.links: list[VehicleLink] = []
        try:
            for k, v in enumerate(vehicles):
                conf = LinkConfig.for_vehicle(
                    k, v.airframe.kind, gcs_host=cfg.gcs_host, base_port=cfg.base_port, rate_hz=cfg.rate_hz
                )
                link = VehicleLink(conf, on_event=self._event_fn(v.name))
                self.links.append(link)
                self.publish_mission(k)
        except BaseException:
            self.close()
            raise

    def _event_fn(self, name: str):
        return lambda text, level: self.log.event(
            self._t, f"{name}: mavlink: {text}", level=level, name=f"mavlink/{name}"
        )

    def publish_mission(self, k: int) -> None:
        """Tell link ``k`` the vehicle's current mission (what a GCS download returns)."""
        lat, lon, alt = ned_to_geodetic(self.vehicles[k].mission.waypoints, self.origin)
        self.links[k].set_mission(list(zip(lat.tolist(), lon.tolist(), alt.tolist(), strict=False)))

    def tick(self, t: float) -> None:
        self._t = t
        if self.pacer is not None:
            self.pacer.pace(t)
        for k, (v, link) in enumerate(zip(self.vehicles, self.links, strict=False)):
            link.publish(t, v.estimate, v.mission.next_index, v.armed, v.mode, v.threats.intruders, self.origin)
            for cmd in link.poll():
                if v.apply_command(cmd, t):
                    self.publish_mission(k)

    def close(self) -> None:
        for link in self.links:
            link.close()
