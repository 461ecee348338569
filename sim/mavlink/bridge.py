"""One simulated vehicle's MAVLink 2 endpoint (common dialect) over UDP.

The link sends from its own socket to the GCS address (like ``udpout:``) and receives on the
same socket, so a GCS listening on the address (QGroundControl on 14550, or
``mavutil.mavlink_connection('udpin:HOST:PORT')``) learns the vehicle from its packets and
replies to it. Replies to a request go to the address the request came from; telemetry goes to
the configured GCS address. Identity: system id from :class:`LinkConfig`, component id 1
(MAV_COMP_ID_AUTOPILOT1), MAV_AUTOPILOT_GENERIC.

Per tick the runner calls :meth:`VehicleLink.publish` (rate limited inside by sim time) and
:meth:`VehicleLink.poll` (non-blocking, returns typed commands; at most
at most ``_MAX_DATAGRAMS_PER_POLL`` datagrams and ``_MAX_BYTES_PER_POLL`` bytes to parse are
read per call, the rest waits for the next tick).
Nothing a peer sends can make either raise: malformed, unexpected or unauthorised packets are
counted in :attr:`VehicleLink.stats` by kind and summarised through ``on_event(text, level)`` at
most once per second of wall time.

Authority: commands, SET_MODE, mission uploads/clears and position targets are obeyed only from
the configured ground station (``gcs_system_id``, and ``gcs_component_id`` unless ``None``), and
only once a HEARTBEAT from it has arrived; others are refused (COMMAND_ACK DENIED, MISSION_ACK
DENIED, targets dropped). Reads (telemetry requests, mission download, parameters) are answered
to anyone. With a ``signing_key`` only frames signed with it are decoded at all. Every mission
item and position target must lie in the link's :class:`~sim.mavlink.envelope.Envelope`.
"""

from __future__ import annotations

import ipaddress
import math
import socket
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Self

import numpy as np
from pymavlink.dialects.v20 import common as mav

from sim.core.state import VehicleState
from sim.core.threats import IntruderTrack
from sim.geodesy import GeoPoint, geodetic_to_ned
from sim.mavlink import telemetry as tlm
from sim.mavlink.anomalies import AnomalyCounter, EventFn
from sim.mavlink.commands import Arm, Command, MissionUpload, PositionTarget, SetMode
from sim.mavlink.datagram import DECODE_ERRORS, decode_datagram
from sim.mavlink.envelope import Envelope, Refusal
from sim.mavlink.mission import MissionServer, Reply, Waypoint
from sim.mavlink.modes import MODES, decode_mode
from sim.mavlink.signing import signing_state

COMPONENT_ID = mav.MAV_COMP_ID_AUTOPILOT1

_MAX_DATAGRAMS_PER_POLL = 32
_MAX_DATAGRAM_BYTES = 1024  # a MAVLink 2 frame is at most 280 bytes; larger datagrams are dropped unparsed
_MAX_BYTES_PER_POLL = 8192
_FORCE_ARM_MAGIC = 21196
_MISSION_MESSAGES = {
    "MISSION_COUNT",
    "MISSION_ITEM_INT",
    "MISSION_ITEM",
    "MISSION_REQUEST_LIST",
    "MISSION_REQUEST_INT",
    "MISSION_REQUEST",
    "MISSION_CLEAR_ALL",
    "MISSION_ACK",
}
# messages that change the vehicle: only from the authorised ground station
_CONTROL_MESSAGES = {
    "COMMAND_LONG",
    "COMMAND_INT",
    "SET_MODE",
    "SET_POSITION_TARGET_LOCAL_NED",
    "MISSION_COUNT",
    "MISSION_ITEM_INT",
    "MISSION_ITEM",
    "MISSION_CLEAR_ALL",
    "PARAM_SET",
}
_ACCEL_BITS = (
    mav.POSITION_TARGET_TYPEMASK_AX_IGNORE
    | mav.POSITION_TARGET_TYPEMASK_AY_IGNORE
    | mav.POSITION_TARGET_TYPEMASK_AZ_IGNORE
)


@dataclass(frozen=True, slots=True)
class LinkConfig:
    """Where and how one vehicle talks MAVLink.

    ``vehicle_type``: the airframe kind, ``"fixed_wing"`` (MAV_TYPE_FIXED_WING) or
    ``"multirotor"`` (MAV_TYPE_QUADROTOR). ``rate_hz``: telemetry rate in sim time (SYS_STATUS,
    ATTITUDE, GLOBAL_POSITION_INT, VFR_HUD, MISSION_CURRENT, ADSB_VEHICLE); HEARTBEAT goes at
    ``heartbeat_hz``. ``bind_host``: the local interface (IPv4 address); ``None`` = loopback,
    which then requires a loopback ``gcs_host`` (a non-loopback bind must be asked for);
    ``bind_port`` 0 = any free port. The ground station obeyed: ``gcs_system_id`` /
    ``gcs_component_id`` (``None``: any component of that system). ``signing_key``: 32-byte
    MAVLink 2 signing key (``None``: no signing; never shown in a repr). Mission upload retry
    timer: ``mission_timeout_s`` of wall time per request, ``mission_retries`` repeats. IPv4
    only."""

    system_id: int
    vehicle_type: str = "fixed_wing"
    gcs_host: str = "127.0.0.1"
    gcs_port: int = 14550
    bind_host: str | None = None
    bind_port: int = 0
    rate_hz: float = 4.0
    heartbeat_hz: float = 1.0
    mission_timeout_s: float = 1.5
    mission_retries: int = 5
    gcs_system_id: int = 255
    gcs_component_id: int | None = None
    signing_key: bytes | None = field(default=None, repr=False)

    def __post_init__(self):
        if not 1 <= self.system_id <= 254:
            raise ValueError(f"MAVLink system id must be 1..254, got {self.system_id}")
        if not 1 <= self.gcs_system_id <= 255 or self.gcs_system_id == self.system_id:
            raise ValueError(f"GCS system id must be 1..255 and not the vehicle's, got {self.gcs_system_id}")
        if self.signing_key is not None and len(self.signing_key) != 32:
            raise ValueError("MAVLink signing key must be 32 bytes")
        if self.vehicle_type not in tlm.MAV_TYPES:
            raise ValueError(f"vehicle_type must be one of {sorted(tlm.MAV_TYPES)}, got {self.vehicle_type!r}")
        if not (self.rate_hz > 0.0 and self.heartbeat_hz > 0.0):
            raise ValueError("telemetry and heartbeat rates must be > 0 Hz")

    @classmethod
    def for_vehicle(
        cls, index: int, vehicle_type: str, *, gcs_host: str = "127.0.0.1", base_port: int = 14550, **kw
    ) -> LinkConfig:
        """The default of vehicle number ``index`` (0-based) of a run: system id ``index + 1``,
        GCS port ``base_port + index``."""
        return cls(system_id=index + 1, vehicle_type=vehicle_type, gcs_host=gcs_host, gcs_port=base_port + index, **kw)


class _Every:
    """True once per ``period`` [s] of sim time, keeping the average rate when called at ticks
    that do not divide the period; resets when time goes back."""

    def __init__(self, period: float):
        self.period = period
        self._next: float | None = None

    def due(self, t: float) -> bool:
        if self._next is None or t < self._next - 2.0 * self.period:
            self._next = t
        if t < self._next - 1e-9:
            return False
        self._next += self.period
        if self._next <= t:
            self._next = t + self.period
        return True


def _addresses(config: LinkConfig) -> tuple[tuple[str, int], str]:
    """(GCS address, local interface) of ``config``; ValueError with one line when the GCS host
    does not resolve or is off loopback without an explicit ``bind_host``."""
    try:
        gcs_ip = socket.gethostbyname(config.gcs_host)
    except (OSError, UnicodeError) as exc:
        raise ValueError(f"MAVLink gcs_host {config.gcs_host!r} does not resolve: {exc}") from None
    if config.bind_host is not None:
        return (gcs_ip, config.gcs_port), config.bind_host
    if not ipaddress.ip_address(gcs_ip).is_loopback:
        raise ValueError(
            f"MAVLink gcs_host {config.gcs_host!r} is not on loopback: set bind_host to the interface to expose "
            "the vehicle on (e.g. 0.0.0.0)"
        )
    return (gcs_ip, config.gcs_port), "127.0.0.1"


def _finite_int(x: float) -> int | None:
    return int(x) if math.isfinite(x) else None


class VehicleLink:
    """The MAVLink endpoint of one vehicle (see the module docstring)."""

    def __init__(
        self,
        config: LinkConfig,
        on_event: EventFn | None = None,
        clock: Callable[[], float] = time.monotonic,
        envelope: Envelope | None = None,
    ):
        """``envelope``: where mission items and position targets may be (``None``: anywhere
        finite on the globe)."""
        self.config = config
        self.sysid = config.system_id
        self.envelope = envelope
        self._on_event = on_event
        self._clock = clock
        self._gcs, bind_host = _addresses(config)
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._sock.bind((bind_host, config.bind_port))
        except OSError:
            self._sock.close()
            raise
        self._sock.setblocking(False)
        self._m = mav.MAVLink(None, self.sysid, COMPONENT_ID)
        self._signing = signing_state(config.signing_key) if config.signing_key is not None else None
        if self._signing is not None:
            self._m.signing = self._signing
        self._anomalies = AnomalyCounter(self._event, clock)
        self.packets_rx = 0
        self.packets_tx = 0
        self.gcs_peers: set[tuple[int, int]] = set()
        self.gcs_heard = False  # a HEARTBEAT from the authorised ground station has arrived
        self.mission = MissionServer(
            self._m, self._anomaly, self._event, config.mission_timeout_s, config.mission_retries, self._check_item
        )
        self._heartbeat = _Every(1.0 / config.heartbeat_hz)
        self._telemetry = _Every(1.0 / config.rate_hz)
        self._origin: GeoPoint | None = None
        self._params = [
            ("SYSID_THISMAV", float(self.sysid)),
            ("MAV_TYPE", float(tlm.MAV_TYPES[config.vehicle_type])),
            ("TLM_RATE_HZ", float(config.rate_hz)),
        ]
        self.closed = False

    # -- life cycle -----------------------------------------------------------------------------
    @property
    def local_address(self) -> tuple[str, int]:
        """(host, port) the link sends from and receives on."""
        return self._sock.getsockname()

    @property
    def stats(self) -> Counter[str]:
        """Anomalies so far, by kind."""
        return self._anomalies.stats

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            self._sock.close()
            self._anomalies.flush(force=True)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- outgoing -------------------------------------------------------------------------------
    def set_mission(self, waypoints: Sequence[Waypoint]) -> None:
        """The mission a GCS download returns: (lat [deg], lon [deg], alt MSL [m]) per waypoint.
        A completed upload replaces it too."""
        self.mission.mission = [(float(lat), float(lon), float(alt)) for lat, lon, alt in waypoints]

    def publish(
        self,
        t: float,
        state: VehicleState,
        mission_current: int,
        armed: bool,
        mode: str,
        intruders: Sequence[IntruderTrack],
        origin: GeoPoint,
    ) -> None:
        """Send what is due at sim time ``t`` [s]: HEARTBEAT at ``heartbeat_hz``; SYS_STATUS,
        ATTITUDE, GLOBAL_POSITION_INT, VFR_HUD, MISSION_CURRENT (``mission_current`` = index of
        the waypoint being flown to) and one ADSB_VEHICLE per intruder at ``rate_hz``;
        HOME_POSITION (= ``origin``) whenever the origin changes. ``mode`` is a name of
        :data:`~sim.mavlink.modes.MODES` (ValueError otherwise: a caller bug, not a packet).
        May be called more often than the rates."""
        mode_spec = MODES.get(mode)
        if mode_spec is None:
            raise ValueError(f"unknown mode {mode!r}, expected one of {sorted(MODES)}")
        if origin != self._origin:
            self._origin = origin
            self.mission.home_alt_m = origin.alt_m
            self._send(tlm.home_position(self._m, origin), self._gcs)
        self.mission.current_seq = mission_current
        if self._heartbeat.due(t):
            self._send(tlm.heartbeat(self._m, self.config.vehicle_type, mode_spec, armed), self._gcs)
        if not self._telemetry.due(t):
            return
        if not tlm.is_finite(state):
            self._anomaly("nonfinite_state", f"state at t={t:.3f} s has non-finite values, not sent", "error")
            return
        m, gcs = self._m, self._gcs
        comm_errors = sum(n for k, n in self.stats.items() if k in DECODE_ERRORS)
        self._send(tlm.sys_status(m, comm_errors), gcs)
        self._send(tlm.attitude(m, state), gcs)
        self._send(tlm.global_position_int(m, state, origin), gcs)
        self._send(tlm.vfr_hud(m, state), gcs)
        self._send(tlm.mission_current(m, mission_current, len(self.mission.mission)), gcs)
        for track in intruders:
            self._send(tlm.adsb_vehicle(m, track, origin, t), gcs)

    def _send(self, msg: mav.MAVLink_message, addr: tuple[str, int]) -> None:
        buf = msg.pack(self._m)
        self._m.seq = (self._m.seq + 1) % 256
        try:
            self._sock.sendto(buf, addr)
            self.packets_tx += 1
        except OSError as exc:
            self._anomaly("send_error", f"{msg.get_type()} to {addr}: {exc}")

    # -- incoming -------------------------------------------------------------------------------
    def poll(self) -> list[Command]:
        """Read every datagram waiting (without blocking), answer what needs an answer, and
        return the commands for the vehicle in arrival order."""
        now = self._clock()
        commands: list[Command] = []
        parsed = 0
        for _ in range(_MAX_DATAGRAMS_PER_POLL):
            if parsed >= _MAX_BYTES_PER_POLL:
                break
            try:
                data, addr = self._sock.recvfrom(_MAX_DATAGRAM_BYTES + 1)
            except (BlockingIOError, InterruptedError):
                break
            except OSError as exc:  # e.g. ICMP port unreachable reported on some platforms
                self._anomaly("socket_error", str(exc))
                break
            if len(data) > _MAX_DATAGRAM_BYTES:
                self._anomaly("oversize", f"datagram over {_MAX_DATAGRAM_BYTES} bytes dropped (from {addr[0]})")
                continue
            parsed += len(data)
            decoded = decode_datagram(data, self._signing)
            for kind, detail in decoded.anomalies:
                self._anomaly(kind, f"{detail} (from {addr[0]}:{addr[1]})")
            for msg in decoded.messages:
                self.packets_rx += 1
                try:
                    cmd = self._dispatch(msg, addr, now)
                except Exception as exc:  # noqa: BLE001 - a peer must never crash the run
                    self._anomaly("handler_error", f"{msg.get_type()}: {type(exc).__name__}: {exc}", "error")
                    continue
                if cmd is not None:
                    commands.append(cmd)
        self.mission.check_timeout(now)
        self._anomalies.flush(now)
        return commands

    def _authorised(self, msg: mav.MAVLink_message) -> bool:
        c = self.config
        src_sys, src_comp = msg.get_srcSystem(), msg.get_srcComponent()
        return src_sys == c.gcs_system_id and c.gcs_component_id in (None, src_comp)

    def _refuse(self, msg: mav.MAVLink_message, reply: Reply) -> None:
        """Answer a control message from a sender that is not (yet) the ground station."""
        kind, src = msg.get_type(), (msg.get_srcSystem(), msg.get_srcComponent())
        why = "before its heartbeat" if self._authorised(msg) else "not the ground station"
        self._anomaly("unauthorised", f"{kind} from {src[0]}/{src[1]} refused: {why}")
        if kind in ("COMMAND_LONG", "COMMAND_INT", "SET_MODE"):
            cmd = msg.command if kind != "SET_MODE" else mav.MAVLINK_MSG_ID_SET_MODE
            reply(self._m.command_ack_encode(cmd, mav.MAV_RESULT_DENIED, 0, 0, *src))
        elif kind.startswith("MISSION_"):
            reply(self._m.mission_ack_encode(*src, mav.MAV_MISSION_DENIED, msg.mission_type))

    def _dispatch(self, msg: mav.MAVLink_message, addr: tuple[str, int], now: float) -> Command | None:
        kind = msg.get_type()
        target = getattr(msg, "target_system", 0)
        target_comp = getattr(msg, "target_component", 0)
        if target not in (0, self.sysid) or target_comp not in (0, COMPONENT_ID):
            self._anomaly("wrong_target", f"{kind} for {target}/{target_comp}, this vehicle is {self.sysid}/1")
            return None

        def reply(out: mav.MAVLink_message) -> None:
            self._send(out, addr)

        if kind in _CONTROL_MESSAGES and not (self.gcs_heard and self._authorised(msg)):
            self._refuse(msg, reply)
            return None
        if kind in _MISSION_MESSAGES:
            waypoints = self.mission.handle(msg, reply, now)
            return MissionUpload(tuple(waypoints)) if waypoints is not None else None
        if kind == "HEARTBEAT":
            self._on_heartbeat(msg, addr)
        elif kind in ("COMMAND_LONG", "COMMAND_INT"):
            return self._on_command(msg, reply)
        elif kind == "SET_MODE":
            return self._on_set_mode(msg, reply)
        elif kind == "SET_POSITION_TARGET_LOCAL_NED":
            return self._on_position_target(msg)
        elif kind == "PARAM_REQUEST_LIST":
            for i in range(len(self._params)):
                reply(self._param_value(i))
        elif kind == "PARAM_REQUEST_READ":
            self._on_param_read(msg, reply)
        elif kind == "PARAM_SET":
            self._on_param_set(msg, reply)
        else:
            self._anomaly(f"unhandled:{kind}", f"{kind} ignored", "debug")
        return None

    def _on_heartbeat(self, msg, addr) -> None:
        peer = (msg.get_srcSystem(), msg.get_srcComponent())
        if not self.gcs_heard and self._authorised(msg):
            self.gcs_heard = True
            self._event(f"ground station {peer[0]}/{peer[1]} heard: commands accepted from it", "info")
        if peer not in self.gcs_peers:
            self.gcs_peers.add(peer)
            self._event(
                f"peer system {peer[0]} component {peer[1]} (MAV_TYPE {msg.type}) seen at {addr[0]}:{addr[1]}", "info"
            )

    def _on_command(self, msg, reply: Reply) -> Command | None:
        cmd = msg.command

        def ack(result: int) -> None:
            reply(self._m.command_ack_encode(cmd, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()))

        if cmd == mav.MAV_CMD_COMPONENT_ARM_DISARM:
            if msg.param1 not in (0.0, 1.0):
                self._anomaly("bad_command", f"arm/disarm with param1={msg.param1}")
                ack(mav.MAV_RESULT_DENIED)
                return None
            ack(mav.MAV_RESULT_ACCEPTED)
            return Arm(msg.param1 == 1.0, force=msg.param2 == _FORCE_ARM_MAGIC)
        if cmd == mav.MAV_CMD_DO_SET_MODE:
            return self._set_mode(_finite_int(msg.param1), _finite_int(msg.param2), ack)
        if cmd == mav.MAV_CMD_REQUEST_MESSAGE and msg.param1 == mav.MAVLINK_MSG_ID_HOME_POSITION:
            if self._origin is None:
                ack(mav.MAV_RESULT_TEMPORARILY_REJECTED)
                return None
            ack(mav.MAV_RESULT_ACCEPTED)
            reply(tlm.home_position(self._m, self._origin))
            return None
        self._anomaly("unsupported_command", f"command {cmd} not supported", "debug")
        ack(mav.MAV_RESULT_UNSUPPORTED)
        return None

    def _on_set_mode(self, msg, reply: Reply) -> Command | None:
        """SET_MODE (deprecated message) is acknowledged like ArduPilot does: COMMAND_ACK with
        ``command`` = the SET_MODE message id (11)."""

        def ack(result: int) -> None:
            reply(
                self._m.command_ack_encode(
                    mav.MAVLINK_MSG_ID_SET_MODE, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()
                )
            )

        return self._set_mode(msg.base_mode, msg.custom_mode, ack)

    def _set_mode(self, base: int | None, custom: int | None, ack: Callable[[int], None]) -> Command | None:
        mode = decode_mode(base, custom) if base is not None and custom is not None else None
        if mode is None:
            self._anomaly("unknown_mode", f"mode request base_mode={base} custom_mode={custom} names no mode")
            ack(mav.MAV_RESULT_DENIED)
            return None
        ack(mav.MAV_RESULT_ACCEPTED)
        return SetMode(mode.name)

    def _on_position_target(self, msg) -> Command | None:
        if msg.coordinate_frame != mav.MAV_FRAME_LOCAL_NED:
            self._anomaly(
                "unsupported_frame",
                f"SET_POSITION_TARGET_LOCAL_NED in frame {msg.coordinate_frame} (only MAV_FRAME_LOCAL_NED)",
            )
            return None
        mask = msg.type_mask
        if ~mask & _ACCEL_BITS:
            self._anomaly("position_target_accel", "acceleration/force setpoints are not supported, ignored")

        def vector(shift: int, values: tuple[float, float, float]) -> np.ndarray | None:
            ignored = [(mask >> (shift + i)) & 1 for i in range(3)]
            if all(ignored):
                return None
            return np.array([math.nan if ig else v for ig, v in zip(ignored, values, strict=False)])

        pos = vector(0, (msg.x, msg.y, msg.z))
        vel = vector(3, (msg.vx, msg.vy, msg.vz))
        yaw = None if mask & mav.POSITION_TARGET_TYPEMASK_YAW_IGNORE else msg.yaw
        yaw_rate = None if mask & mav.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE else msg.yaw_rate
        if pos is None and vel is None and yaw is None and yaw_rate is None:
            self._anomaly("position_target_empty", f"type_mask {mask:#06x} ignores every field")
            return None
        refusal = self._check_target(pos, vel, yaw, yaw_rate)
        if refusal is not None:
            self._anomaly("position_target_refused", refusal)
            return None
        return PositionTarget(msg.time_boot_ms, pos, vel, yaw, yaw_rate)

    def _check_target(
        self, pos: np.ndarray | None, vel: np.ndarray | None, yaw: float | None, yaw_rate: float | None
    ) -> str | None:
        """Why a position target is refused, or ``None``: no infinite value (NaN marks an ignored
        axis), a finite yaw and yaw rate, and a full position in the envelope."""
        vectors = [v for v in (pos, vel) if v is not None]
        if any(np.isinf(v).any() for v in vectors) or any(
            x is not None and not math.isfinite(x) for x in (yaw, yaw_rate)
        ):
            return "non-finite value"
        if pos is not None and not np.isnan(pos).any() and self.envelope is not None:
            refusal = self.envelope.check(pos)
            if refusal is not None:
                return refusal.reason
        return None

    def _check_item(self, wp: Waypoint) -> Refusal | None:
        if self.envelope is None:
            return None
        if self._origin is None:
            return Refusal(mav.MAV_MISSION_ERROR, "home position not known yet")
        return self.envelope.check(geodetic_to_ned(*wp, self._origin))

    # -- parameters (a small read-only set, so that GCSs finish connecting) ---------------------
    def _param_value(self, index: int) -> mav.MAVLink_message:
        name, value = self._params[index]
        return self._m.param_value_encode(name.encode(), value, mav.MAV_PARAM_TYPE_REAL32, len(self._params), index)

    def _param_index(self, param_id: str) -> int | None:
        return next((i for i, (n, _) in enumerate(self._params) if n == param_id), None)

    def _on_param_read(self, msg, reply: Reply) -> None:
        index = msg.param_index if msg.param_index >= 0 else self._param_index(msg.param_id)
        if index is None or not 0 <= index < len(self._params):
            self._anomaly("param_unknown", f"parameter {msg.param_id!r} / {msg.param_index} requested")
            return
        reply(self._param_value(index))

    def _on_param_set(self, msg, reply: Reply) -> None:
        index = self._param_index(msg.param_id)
        if index is None:
            self._anomaly("param_unknown", f"PARAM_SET of unknown parameter {msg.param_id!r}")
            return
        self._anomaly("param_set_refused", f"parameter {msg.param_id} is read-only")
        reply(self._param_value(index))

    # -- reporting ------------------------------------------------------------------------------
    def _event(self, text: str, level: str) -> None:
        if self._on_event is not None:
            self._on_event(f"mavlink sys {self.sysid}: {text}", level)

    def _anomaly(self, kind: str, detail: str, level: str = "warning") -> None:
        self._anomalies.count(kind, detail, level)
