"""The vehicle side of the MAVLink mission protocol (mission_type MISSION only).

Upload (GCS -> vehicle): MISSION_COUNT, then the vehicle requests each item with
MISSION_REQUEST_INT and the GCS answers with MISSION_ITEM_INT (a MISSION_ITEM answer is accepted
too); after the last item the vehicle sends MISSION_ACK(ACCEPTED) and the upload is complete.
A request unanswered for ``timeout_s`` (wall clock: the GCS is a real program) is sent again up to
``retries`` times, then the upload is cancelled (MISSION_ACK OPERATION_CANCELLED). An item ahead
of the expected one cancels with INVALID_SEQUENCE; a repeated earlier item is ignored and the
expected one requested again. Invalid items cancel with the specific MAV_MISSION_RESULT. A
MISSION_ACK from the uploading GCS cancels the upload from its side.

Download (vehicle -> GCS): MISSION_REQUEST_LIST is answered with MISSION_COUNT and each
MISSION_REQUEST_INT / MISSION_REQUEST with the item (frame GLOBAL[_INT], altitude MSL). Fence and
rally lists are reported empty; uploads of them are refused (UNSUPPORTED). Clearing the mission
(MISSION_CLEAR_ALL, or a count of 0) is refused (DENIED): a simulated vehicle always has a mission.

Item coordinates: frames GLOBAL / GLOBAL_INT (altitude MSL) and GLOBAL_RELATIVE_ALT[_INT]
(altitude above home = the scenario origin); other frames are refused (UNSUPPORTED_FRAME). Each
waypoint must pass the ``check`` given (the vehicle's envelope: its MAV_MISSION_RESULT otherwise).
NAV_WAYPOINT items are waypoints; the other positional NAV commands (loiter, take-off, land) are
flown as plain waypoints at their position (warning event); DO_/CONDITION_ commands are skipped
(info event); other NAV commands are refused (UNSUPPORTED).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

from pymavlink.dialects.v20 import common as mav

from sim.mavlink.envelope import Refusal

Waypoint = tuple[float, float, float]  # lat [deg], lon [deg], alt MSL [m]
Reply = Callable[[mav.MAVLink_message], None]
Anomaly = Callable[[str, str], None]  # (kind, detail)
Event = Callable[[str, str], None]  # (text, level)
Check = Callable[[Waypoint], Refusal | None]  # why a waypoint is refused, None if accepted

_MSL_FRAMES = {mav.MAV_FRAME_GLOBAL, mav.MAV_FRAME_GLOBAL_INT}
_RELATIVE_FRAMES = {mav.MAV_FRAME_GLOBAL_RELATIVE_ALT, mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT}
_POSITIONAL_NAV = {
    mav.MAV_CMD_NAV_LOITER_UNLIM,
    mav.MAV_CMD_NAV_LOITER_TURNS,
    mav.MAV_CMD_NAV_LOITER_TIME,
    mav.MAV_CMD_NAV_LAND,
    mav.MAV_CMD_NAV_TAKEOFF,
    mav.MAV_CMD_NAV_LOITER_TO_ALT,
}
_MISSION = mav.MAV_MISSION_TYPE_MISSION


class _ItemError(Exception):
    def __init__(self, result: int, text: str):
        super().__init__(text)
        self.result = result


@dataclass
class _Upload:
    count: int
    src: tuple[int, int]  # GCS (system, component)
    reply: Reply
    deadline: float
    retries_left: int
    next_seq: int = 0
    waypoints: list[Waypoint] = field(default_factory=list)


class MissionServer:
    """Mission protocol state of one vehicle. ``home_alt_m`` (MSL [m]) must be set before items
    with relative altitude can be accepted; ``mission`` is what a download returns."""

    def __init__(
        self,
        encoder: mav.MAVLink,
        anomaly: Anomaly,
        event: Event,
        timeout_s: float = 1.5,
        retries: int = 5,
        check: Check | None = None,
    ):
        self._m = encoder
        self._check = check
        self._anomaly = anomaly
        self._event = event
        self.timeout_s = timeout_s
        self.retries = retries
        self.home_alt_m: float | None = None
        self.mission: list[Waypoint] = []
        self.current_seq = 0
        self._upload: _Upload | None = None

    @property
    def uploading(self) -> bool:
        return self._upload is not None

    # -- dispatch ---------------------------------------------------------------------------
    def handle(self, msg: mav.MAVLink_message, reply: Reply, now: float) -> list[Waypoint] | None:
        """Process one mission message from the GCS; returns the waypoints when it completed an
        upload. ``now`` is wall-clock time [s] for the retry timer."""
        kind = msg.get_type()
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        if kind == "MISSION_COUNT":
            self._on_count(msg, src, reply, now)
        elif kind in ("MISSION_ITEM_INT", "MISSION_ITEM"):
            return self._on_item(msg, src, now)
        elif kind == "MISSION_REQUEST_LIST":
            reply(
                self._m.mission_count_encode(
                    *src, len(self.mission) if msg.mission_type == _MISSION else 0, msg.mission_type
                )
            )
        elif kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            self._on_request(msg, src, reply, kind == "MISSION_REQUEST_INT")
        elif kind == "MISSION_CLEAR_ALL":
            self._event("mission clear refused: the simulated vehicle keeps a mission", "warning")
            reply(self._m.mission_ack_encode(*src, mav.MAV_MISSION_DENIED, msg.mission_type))
        elif kind == "MISSION_ACK" and self._upload is not None and self._upload.src == src:
            self._upload = None  # the GCS gave up on its upload
            self._event(f"mission upload cancelled by the GCS (MISSION_ACK {msg.type})", "warning")
        # any other MISSION_ACK ends a download: nothing to do, downloads are stateless
        return None

    def check_timeout(self, now: float) -> None:
        """Re-request the awaited item or cancel the upload when the GCS has gone quiet."""
        up = self._upload
        if up is None or now < up.deadline:
            return
        if up.retries_left > 0:
            up.retries_left -= 1
            self._anomaly("mission_retry", f"no reply for mission item {up.next_seq}, requesting again")
            self._request(up, now)
            return
        self._anomaly(
            "mission_timeout",
            f"mission upload cancelled: item {up.next_seq} of {up.count} never arrived after {self.retries} retries",
        )
        self._finish(up, mav.MAV_MISSION_OPERATION_CANCELLED)

    # -- upload -----------------------------------------------------------------------------
    def _on_count(self, msg, src, reply: Reply, now: float) -> None:
        if msg.mission_type != _MISSION:
            self._event(f"mission upload of type {msg.mission_type} refused (only missions)", "warning")
            reply(self._m.mission_ack_encode(*src, mav.MAV_MISSION_UNSUPPORTED, msg.mission_type))
            return
        if msg.count == 0:
            self._event("mission clear (count 0) refused: the simulated vehicle keeps a mission", "warning")
            reply(self._m.mission_ack_encode(*src, mav.MAV_MISSION_DENIED, _MISSION))
            return
        up = self._upload
        if up is not None and up.src == src and up.count == msg.count and up.next_seq == 0:
            self._request(up, now)  # a repeated MISSION_COUNT: our first request was lost
            return
        if up is not None:
            self._anomaly("mission_restarted", f"mission upload restarted at item {up.next_seq} of {up.count}")
        self._upload = _Upload(msg.count, src, reply, 0.0, self.retries)
        self._request(self._upload, now)

    def _on_item(self, msg, src, now: float) -> list[Waypoint] | None:
        up = self._upload
        if up is None or up.src != src or msg.mission_type != _MISSION:
            self._anomaly("mission_unexpected_item", f"mission item {msg.seq} outside an upload")
            return None
        if msg.seq < up.next_seq:
            self._anomaly("mission_duplicate_item", f"mission item {msg.seq} repeated")
            self._request(up, now)
            return None
        if msg.seq > up.next_seq:
            self._anomaly("mission_sequence", f"mission item {msg.seq} arrived, expected {up.next_seq}")
            self._finish(up, mav.MAV_MISSION_INVALID_SEQUENCE)
            return None
        try:
            wp = self._waypoint(msg)
        except _ItemError as err:
            self._anomaly("mission_invalid_item", f"mission item {msg.seq}: {err}")
            self._finish(up, err.result)
            return None
        if wp is not None:
            up.waypoints.append(wp)
        up.next_seq += 1
        if up.next_seq < up.count:
            self._request(up, now)
            return None
        if not up.waypoints:
            self._event("mission upload refused: no waypoint in it", "warning")
            self._finish(up, mav.MAV_MISSION_DENIED)
            return None
        self.mission, self.current_seq = list(up.waypoints), 0
        self._finish(up, mav.MAV_MISSION_ACCEPTED)
        self._event(f"mission of {len(self.mission)} waypoints uploaded", "info")
        return list(self.mission)

    def _request(self, up: _Upload, now: float) -> None:
        up.deadline = now + self.timeout_s
        up.reply(self._m.mission_request_int_encode(*up.src, up.next_seq, _MISSION))

    def _finish(self, up: _Upload, result: int) -> None:
        """End the upload ``up`` with ``result`` sent to its sender."""
        self._upload = None
        up.reply(self._m.mission_ack_encode(*up.src, result, _MISSION))

    def _waypoint(self, msg) -> Waypoint | None:
        """(lat, lon, alt MSL) of an item, ``None`` for a skipped non-NAV command."""
        cmd = msg.command
        if cmd > mav.MAV_CMD_NAV_LAST:
            self._event(f"mission item {msg.seq}: command {cmd} skipped (not a navigation command)", "info")
            return None
        if cmd != mav.MAV_CMD_NAV_WAYPOINT and cmd not in _POSITIONAL_NAV:
            raise _ItemError(mav.MAV_MISSION_UNSUPPORTED, f"navigation command {cmd} not supported")
        if cmd != mav.MAV_CMD_NAV_WAYPOINT:
            self._event(f"mission item {msg.seq}: command {cmd} flown as a plain waypoint", "warning")
        scale = 1e-7 if msg.get_type() == "MISSION_ITEM_INT" else 1.0
        lat, lon, z = msg.x * scale, msg.y * scale, float(msg.z)
        if not (math.isfinite(lat) and -90.0 <= lat <= 90.0):
            raise _ItemError(mav.MAV_MISSION_INVALID_PARAM5_X, f"latitude {lat} out of range")
        if not (math.isfinite(lon) and -180.0 <= lon <= 180.0):
            raise _ItemError(mav.MAV_MISSION_INVALID_PARAM6_Y, f"longitude {lon} out of range")
        if not math.isfinite(z):
            raise _ItemError(mav.MAV_MISSION_INVALID_PARAM7, f"altitude {z} not finite")
        if msg.frame in _MSL_FRAMES:
            wp = (lat, lon, z)
        elif msg.frame in _RELATIVE_FRAMES:
            if self.home_alt_m is None:
                raise _ItemError(mav.MAV_MISSION_ERROR, "relative altitude before home is known")
            wp = (lat, lon, z + self.home_alt_m)
        else:
            raise _ItemError(mav.MAV_MISSION_UNSUPPORTED_FRAME, f"frame {msg.frame} not supported")
        refusal = self._check(wp) if self._check is not None else None
        if refusal is not None:
            raise _ItemError(refusal.result, refusal.reason)
        return wp

    # -- download ---------------------------------------------------------------------------
    def _on_request(self, msg, src, reply: Reply, as_int: bool) -> None:
        if msg.mission_type != _MISSION or not 0 <= msg.seq < len(self.mission):
            self._anomaly("mission_bad_request", f"mission item {msg.seq} requested, have {len(self.mission)}")
            reply(self._m.mission_ack_encode(*src, mav.MAV_MISSION_INVALID_SEQUENCE, msg.mission_type))
            return
        lat, lon, alt = self.mission[msg.seq]
        current = int(msg.seq == self.current_seq)
        cmd = mav.MAV_CMD_NAV_WAYPOINT
        if as_int:
            reply(
                self._m.mission_item_int_encode(
                    *src,
                    msg.seq,
                    mav.MAV_FRAME_GLOBAL_INT,
                    cmd,
                    current,
                    1,
                    0.0,
                    0.0,
                    0.0,
                    math.nan,
                    round(lat * 1e7),
                    round(lon * 1e7),
                    alt,
                    _MISSION,
                )
            )
        else:
            reply(
                self._m.mission_item_encode(
                    *src,
                    msg.seq,
                    mav.MAV_FRAME_GLOBAL,
                    cmd,
                    current,
                    1,
                    0.0,
                    0.0,
                    0.0,
                    math.nan,
                    lat,
                    lon,
                    alt,
                    _MISSION,
                )
            )
