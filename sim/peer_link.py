"""The vehicle-to-vehicle link of the UTM's response mode (spec §7.1, fig. 6.30;
:mod:`avoidance.utm.response`): vehicles with a ``[vehicle.peer_link]`` broadcast their position
notification every UTM frame and pass the rules planners' claims and acknowledgements.

A message from A to B leaves on A's link (latency, loss, A's outages at sending and at arrival,
:class:`sim.utm_link.Link`) and is received unless B's link is in an outage at its arrival;
it is handed over at the first tick at or after its arrival (the log rate). A vehicle whose
rules planner is not flying (a ground-station mode planner) receives nothing and sends only its
notification. Every message is logged when sent, with the time it is received (null: lost):
``/utm/peer/notification``, ``/utm/peer/claim``, ``/utm/peer/ack``. Frames: GCF (ENU) [m] from
the scenario origin, sim seconds.
"""

from __future__ import annotations

import math

from avoidance.rules.planner import RulesAvoider
from avoidance.utm.response import PeerMessage
from sim import log_schemas as S
from sim.core.frames import ned_to_enu
from sim.mcap_log import McapLog
from sim.utm_link import Link, Queue
from sim.vehicle import Vehicle

_META = {"frame": "GCF = ENU [m] from the scenario origin"}
_SCHEMAS = {"notification": S.UTM_PEER_NOTIFICATION, "claim": S.UTM_PEER_CLAIM, "ack": S.UTM_PEER_ACK}


class PeerNetwork:
    """The vehicle-to-vehicle links of the vehicles in ``links`` (the others have none)."""

    def __init__(self, vehicles: list[Vehicle], links: dict[str, Link], frame: float, log: McapLog, tick_hz: float):
        """``frame`` [s]: the notification period (the UTM frame); ``tick_hz``: the rate
        :meth:`tick` is called at (the log rate)."""
        self.vehicles = {v.name: v for v in vehicles if v.name in links}
        self.links, self.frame, self.log, self.tick_hz = links, frame, log, tick_hz
        self.queue = Queue()
        self.frame_no = 0

    def tick(self, t: float) -> None:
        """Deliver what arrived by ``t`` [s] (acknowledgements go out at once), send the rules
        planners' claims, and every frame each vehicle's notification."""
        for m in self.queue.due(t):
            p = self._listening(m.to)
            if p is not None:
                self._send(t, p.receive_peer(m, t))
        for name in self.vehicles:
            p = self._listening(name)
            if p is not None:
                self._send(t, p.peer_outbox())
        if t + 1e-9 >= self.frame_no * self.frame:
            self.frame_no += 1
            for name, v in self.vehicles.items():
                est = v.estimate
                pos, vel = ned_to_enu(est.pos_ned), ned_to_enu(est.vel_ned)
                self._send(t, [PeerMessage("notification", name, None, t, pos=pos, vel=vel)])

    def _listening(self, name: str | None) -> RulesAvoider | None:
        """The rules planner flying ``name`` with a peer link, else None."""
        p = self.vehicles[name].planner if name in self.vehicles else None
        return p if isinstance(p, RulesAvoider) and p.peers is not None else None

    def _send(self, t: float, msgs: list[PeerMessage]) -> None:
        for m in msgs:
            for to in [m.to] if m.to is not None else [n for n in self.vehicles if n != m.sender]:
                due = self.links[m.sender].arrival(t)
                if due is not None and not self.links[to].up(due):
                    due = None
                self._log(t, m, to, due)
                if due is not None:
                    self.queue.put(
                        due, m if m.to is not None else PeerMessage(m.kind, m.sender, to, m.t, m.case, m.pos, m.vel)
                    )

    def _log(self, t: float, m: PeerMessage, to: str, due: float | None) -> None:
        received = None if due is None else math.ceil(due * self.tick_hz - 1e-6) / self.tick_hz
        body: dict = {"t": t, "from": m.sender, "to": to, "received_t": received}
        if m.case is not None:
            body["case"] = m.case.record()
        if m.pos is not None and m.vel is not None:
            body |= {"pos_enu": m.pos, "vel_enu": m.vel}
        self.log.write_json(f"/utm/peer/{m.kind}", t, body, _SCHEMAS[m.kind], _META)
