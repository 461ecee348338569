"""The UTM authorities of one airspace (spec §7.1): one over the whole airspace, or one per static
cluster (``utm.cluster``), and the ground network between them (:class:`AirspaceState`).

Per log tick every authority first delivers what has arrived; when a decision frame starts (the
same frame clock for all), the network assigns each vehicle its director, every authority
assesses its cases (:meth:`UtmAuthority.assess`), the network decides which chains close (a pair
closes in every book holding it once it has been quiet in all of them), and every authority
closes those and directs (:meth:`UtmAuthority.direct`). The director is the authority whose box holds the
vehicle's newest notification any of them took (before the first, its departure point; none
holds it: uncontrolled airspace). Assigning it on the shared picture, not on each authority's
own newest notification, keeps one director per vehicle and frame when a notification reached
one authority and was lost to another (each authority deciding alone, both the old and the new
one directed a vehicle crossing a boundary in that frame: S11 under four authorities, seeds 14
and 15). With clusters the authorities also share the open cases' heads
(:class:`avoidance.utm.cases.SharedHeads`): a pair opened by one is opened by the others with its
head as soon as they assess it, and closed by all of them in one frame, so the books agree on
collision points, roles and roundabout centres in every frame whatever notifications each lost.
Sim seconds; GCF (ENU) [m].
"""

from __future__ import annotations

from avoidance.utm.cases import SharedHeads, closing_together
from sim.core.frames import ned_to_enu
from sim.mcap_log import McapLog
from sim.scenario import Utm
from sim.utm_authority import AirspaceState, UtmAuthority
from sim.utm_link import Link
from sim.vehicle import Vehicle


class UtmAirspace:
    def __init__(
        self,
        cfg: Utm,
        vehicles: list[Vehicle],
        links: dict[str, Link],
        log: McapLog,
        origin_alt: float,
        tick_hz: float,
        peer_linked: frozenset[str] = frozenset(),
    ):
        """Arguments as :class:`UtmAuthority`; one authority per ``cfg.cluster`` (none: one)."""
        self.state = AirspaceState(heads=SharedHeads() if cfg.cluster else None)
        # GCF [m]: where each vehicle stood at the start (its director before a notification)
        self.departure = {v.name: ned_to_enu(v.estimate.pos_ned) for v in vehicles}
        args = (cfg, vehicles, links, log, origin_alt, tick_hz, peer_linked)
        self.authorities = [UtmAuthority(*args, c, self.state) for c in cfg.cluster] or [
            UtmAuthority(*args, None, self.state)
        ]

    def tick(self, t: float) -> None:
        """Deliver what arrived by ``t`` [s]; run a decision frame when one starts."""
        for a in self.authorities:
            a.deliver(t)
        if self.authorities[0].frame_due(t):
            self._assign()
            for a in self.authorities:
                a.assess(t)
            closing = closing_together([a.book for a in self.authorities])
            for a in self.authorities:
                a.direct(t, closing)

    def set_storms(self, storms: list) -> None:
        """The weather service's newest nowcast, to every authority (``utm.weather``)."""
        for a in self.authorities:
            a.storms = storms

    def _assign(self) -> None:
        """Each vehicle's director this frame (:attr:`AirspaceState.director`)."""
        for name, departure in self.departure.items():
            notes = [a.members[name].last_note for a in self.authorities]
            newest = max((n for n in notes if n is not None), key=lambda n: n.t, default=None)
            pos = newest.pos if newest is not None else departure
            self.state.director[name] = next((a.id for a in self.authorities if a.holds(pos)), None)
