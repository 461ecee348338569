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
from sim.mavlink.envelope import DEFAULT_LIMITS, Envelope
from sim.mavlink.pacing import WallClockPacer
from sim.mavlink.signing import load_key
from sim.mcap_log import McapLog


def envelope(cfg, kind: str, fences) -> Envelope:
    """The envelope of a vehicle of airframe ``kind`` under the scenario's ``[mavlink]`` ``cfg``."""
    height, reach = DEFAULT_LIMITS[kind]
    return Envelope(
        cfg.max_height if cfg.max_height is not None else height,
        cfg.max_range if cfg.max_range is not None else reach,
        tuple(fences),
    )


class MavlinkSession:
    def __init__(self, cfg, vehicles: list, origin: GeoPoint, log: McapLog, fences=()):
        """``cfg``: the scenario's ``[mavlink]``; ``fences``: the geofences (local NED) every
        mission item and position target must respect. ValueError (one line) on a bad
        address or key file."""
        self.vehicles = vehicles
        self.origin = origin
        self.log = log
        self.pacer = WallClockPacer(cfg.pace) if cfg.pace > 0 else None
        self._t = 0.0
        self.links: list[VehicleLink] = []
        key = load_key(cfg.signing_key_file) if cfg.signing_key_file is not None else None
        try:
            for k, v in enumerate(vehicles):
                conf = LinkConfig.for_vehicle(
                    k,
                    v.airframe.kind,
                    gcs_host=cfg.gcs_host,
                    base_port=cfg.base_port,
                    rate_hz=cfg.rate_hz,
                    bind_host=cfg.bind_host,
                    gcs_system_id=cfg.gcs_system_id,
                    gcs_component_id=cfg.gcs_component_id,
                    signing_key=key,
                )
                link = VehicleLink(
                    conf, on_event=self._event_fn(v.name), envelope=envelope(cfg, v.airframe.kind, fences)
                )
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
