"""MAVLink bridge against a pymavlink GCS on loopback: telemetry, mission protocol, commands,
hostile input. Ports come from binding port 0; every wait has a short timeout."""

import math
import os
import random
import socket
import time

os.environ.setdefault("MAVLINK20", "1")  # before pymavlink.mavutil picks a dialect

import numpy as np
import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mav

from sim.core.state import VehicleState
from sim.core.threats import IntruderTrack
from sim.geodesy import GeoPoint, ned_to_geodetic
from sim.mavlink import (
    MODES,
    Arm,
    LinkConfig,
    MissionUpload,
    PositionTarget,
    SetMode,
    VehicleLink,
)
from sim.mavlink.telemetry import icao_address

SYSID = 7
ORIGIN = GeoPoint(47.0, 8.0, 400.0)


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def make_state(t=1.25) -> VehicleState:
    pos = np.array([120.0, -40.0, -600.0])
    lat, lon, alt = ned_to_geodetic(pos, ORIGIN)
    return VehicleState(
        t=t,
        pos_ned=pos,
        vel_ned=np.array([20.0, -5.0, -1.5]),
        euler=np.array([0.2, -0.05, -2.0]),
        rates_body=np.array([0.01, -0.02, 0.03]),
        alt_msl_m=float(alt),
        lat_deg=float(lat),
        lon_deg=float(lon),
        tas_mps=23.0,
        eas_mps=21.5,
        extra={"throttle": 0.42},
    )


class Harness:
    """A vehicle link and a pymavlink GCS (``udpin``) connected on loopback."""

    def __init__(self, heartbeat=True, envelope=None, gcs_key=None, **cfg):
        """``heartbeat``: the GCS introduces itself (so the link obeys it); ``gcs_key``: the
        GCS signs its frames with this key."""
        port = free_port()
        self.gcs = mavutil.mavlink_connection(
            f"udpin:127.0.0.1:{port}", dialect="common", source_system=255, source_component=190
        )
        if gcs_key is not None:
            self.gcs.setup_signing(gcs_key, sign_outgoing=True)
        self.events: list[tuple[str, str]] = []
        self.link = VehicleLink(
            LinkConfig(system_id=SYSID, gcs_port=port, **cfg),
            on_event=lambda text, level: self.events.append((level, text)),
            envelope=envelope,
        )
        self.commands = []
        self.inbox = []
        self.state = make_state()
        # the GCS learns the vehicle's address from its first packet
        self.link.publish(self.state.t, self.state, 1, True, "AUTO", [], ORIGIN)
        self.first_heartbeat = self.recv("HEARTBEAT")
        assert self.first_heartbeat is not None
        if heartbeat:
            self.gcs.mav.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            self.settle(0.05)

    def recv(self, kind, timeout=2.0):
        """Oldest unread message of ``kind`` (a type or list of types) at the GCS, polling the
        link meanwhile (its commands are kept); other messages stay in the inbox."""
        kinds = {kind} if isinstance(kind, str) else set(kind)
        end = time.monotonic() + timeout
        while True:
            for i, msg in enumerate(self.inbox):
                if msg.get_type() in kinds:
                    return self.inbox.pop(i)
            if time.monotonic() > end:
                return None
            self.commands += self.link.poll()
            msg = self.gcs.recv_match(blocking=True, timeout=0.01)
            if msg is not None and msg.get_type() != "BAD_DATA":
                self.inbox.append(msg)

    def settle(self, seconds=0.1):
        """Let the link read what the GCS sent."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.commands += self.link.poll()
            time.sleep(0.005)

    def drain(self):
        """Forget everything received so far."""
        while self.gcs.recv_match(blocking=False) is not None:
            pass
        self.inbox.clear()

    def close(self):
        self.link.close()
        self.gcs.close()


@pytest.fixture
def h():
    harness = Harness(mission_timeout_s=0.2, mission_retries=2)
    yield harness
    harness.close()


# -- telemetry ---------------------------------------------------------------------------------
def test_heartbeat_identity_and_scaled_telemetry(h):
    hb = h.first_heartbeat
    assert (hb.get_srcSystem(), hb.get_srcComponent()) == (SYSID, mav.MAV_COMP_ID_AUTOPILOT1)
    assert hb.type == mav.MAV_TYPE_FIXED_WING and hb.autopilot == mav.MAV_AUTOPILOT_GENERIC
    assert hb.custom_mode == MODES["AUTO"].custom_mode and hb.system_status == mav.MAV_STATE_ACTIVE
    assert hb.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED and hb.base_mode & mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    s = h.state
    att = h.recv("ATTITUDE")
    assert att.time_boot_ms == 1250
    assert (att.roll, att.pitch, att.yaw) == pytest.approx(tuple(s.euler), abs=1e-6)
    assert (att.rollspeed, att.pitchspeed, att.yawspeed) == pytest.approx(tuple(s.rates_body), abs=1e-6)
    gp = h.recv("GLOBAL_POSITION_INT")
    assert gp.lat == round(s.lat_deg * 1e7) and gp.lon == round(s.lon_deg * 1e7)
    assert gp.alt == round(s.alt_msl_m * 1000) and gp.relative_alt == 600_000
    assert (gp.vx, gp.vy, gp.vz) == (2000, -500, -150)
    assert gp.hdg == round(math.degrees(-2.0 + 2 * math.pi) * 100)
    hud = h.recv("VFR_HUD")
    assert hud.airspeed == pytest.approx(21.5) and hud.groundspeed == pytest.approx(math.hypot(20, 5), rel=1e-6)
    assert hud.climb == pytest.approx(1.5) and hud.throttle == 42 and hud.heading == 245
    assert h.recv("MISSION_CURRENT").seq == 1
    assert h.recv("SYS_STATUS") is not None
    home = h.recv("HOME_POSITION")
    assert (home.latitude, home.longitude, home.altitude) == (470_000_000, 80_000_000, 400_000)


def test_adsb_vehicle_per_intruder(h):
    tracks = [
        IntruderTrack("cessna", 2.0, np.array([1000.0, 0.0, -300.0]), np.array([0.0, 50.0, 2.0])),
        IntruderTrack("uas2", 1.0, np.array([0.0, 500.0, -100.0]), np.array([-10.0, 0.0, 0.0]), cooperative=True),
    ]
    h.drain()
    h.link.publish(2.0, make_state(2.0), 0, True, "AUTO", tracks, ORIGIN)
    got = {}
    while len(got) < 2 and (m := h.recv("ADSB_VEHICLE", timeout=1.0)) is not None:
        got[m.callsign] = m
    assert set(got) == {"cessna", "uas2"}
    c = got["cessna"]
    lat, lon, alt = ned_to_geodetic(tracks[0].pos_ned, ORIGIN)
    assert c.ICAO_address == icao_address("cessna")
    assert c.lat == round(float(lat) * 1e7) and c.lon == round(float(lon) * 1e7)
    assert c.altitude == round(float(alt) * 1000) and c.altitude_type == mav.ADSB_ALTITUDE_TYPE_GEOMETRIC
    assert c.heading == 9000 and c.hor_velocity == 5000 and c.ver_velocity == -200
    assert got["uas2"].emitter_type == mav.ADSB_EMITTER_TYPE_UAV and got["uas2"].tslc == 1


def test_rates_are_limited_by_sim_time():
    """publish at 100 Hz for 3 s of sim time: heartbeat 1 Hz, telemetry at the configured 5 Hz."""
    h = Harness(rate_hz=5.0)
    try:
        h.drain()
        for k in range(1, 301):
            t = h.state.t + k * 0.01
            h.link.publish(t, make_state(t), 0, False, "MANUAL", [], ORIGIN)
        time.sleep(0.1)
        counts = {}
        while (m := h.gcs.recv_match(blocking=False)) is not None:
            counts[m.get_type()] = counts.get(m.get_type(), 0) + 1
        assert counts["HEARTBEAT"] == 3
        assert counts["ATTITUDE"] == 15 and counts["GLOBAL_POSITION_INT"] == 15
    finally:
        h.close()


def test_unknown_mode_name_is_a_caller_error(h):
    with pytest.raises(ValueError, match="unknown mode"):
        h.link.publish(5.0, h.state, 0, True, "LOITER_FOREVER", [], ORIGIN)


# -- mission protocol --------------------------------------------------------------------------
WAYPOINTS = [(47.01, 8.0, 600.0), (47.01, 8.02, 650.0), (47.0, 8.02, 700.0)]


def upload(h, waypoints, frame=mav.MAV_FRAME_GLOBAL_INT, skip=None):
    """The GCS side of a mission upload; returns the final MISSION_ACK."""
    h.gcs.mav.mission_count_send(SYSID, 1, len(waypoints), mav.MAV_MISSION_TYPE_MISSION)
    while (m := h.recv(["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"])) is not None:
        if m.get_type() == "MISSION_ACK":
            return m
        seq = skip if skip is not None and m.seq == 0 else m.seq
        lat, lon, alt = waypoints[seq]
        h.gcs.mav.mission_item_int_send(
            SYSID,
            1,
            seq,
            frame,
            mav.MAV_CMD_NAV_WAYPOINT,
            0,
            1,
            0,
            0,
            0,
            math.nan,
            round(lat * 1e7),
            round(lon * 1e7),
            alt,
            mav.MAV_MISSION_TYPE_MISSION,
        )
    return None


def test_three_waypoint_mission_upload_and_download(h):
    ack = upload(h, WAYPOINTS)
    assert ack.type == mav.MAV_MISSION_ACCEPTED
    h.settle()
    uploads = [c for c in h.commands if isinstance(c, MissionUpload)]
    assert len(uploads) == 1
    assert np.allclose(uploads[0].waypoints, WAYPOINTS, atol=1e-7)
    # the GCS reads it back
    h.gcs.mav.mission_request_list_send(SYSID, 1, mav.MAV_MISSION_TYPE_MISSION)
    assert h.recv("MISSION_COUNT").count == 3
    for seq, (lat, lon, alt) in enumerate(WAYPOINTS):
        h.gcs.mav.mission_request_int_send(SYSID, 1, seq, mav.MAV_MISSION_TYPE_MISSION)
        item = h.recv("MISSION_ITEM_INT")
        assert (item.seq, item.frame, item.command) == (seq, mav.MAV_FRAME_GLOBAL_INT, mav.MAV_CMD_NAV_WAYPOINT)
        assert (item.x, item.y, item.z) == (round(lat * 1e7), round(lon * 1e7), pytest.approx(alt))


def test_relative_altitude_items_are_converted_to_msl(h):
    rel = [(lat, lon, alt - ORIGIN.alt_m) for lat, lon, alt in WAYPOINTS]
    assert upload(h, rel, frame=mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT).type == mav.MAV_MISSION_ACCEPTED
    h.settle()
    (up,) = [c for c in h.commands if isinstance(c, MissionUpload)]
    assert [w[2] for w in up.waypoints] == pytest.approx([w[2] for w in WAYPOINTS])


def test_out_of_sequence_item_is_refused_and_counted(h):
    ack = upload(h, WAYPOINTS, skip=2)
    assert ack.type == mav.MAV_MISSION_INVALID_SEQUENCE
    h.settle()
    assert not [c for c in h.commands if isinstance(c, MissionUpload)]
    assert h.link.stats["mission_sequence"] == 1
    assert any("mission_sequence" in text for _, text in h.events)
    # a stray item outside any upload is counted, not answered
    h.gcs.mav.mission_item_int_send(
        SYSID, 1, 1, mav.MAV_FRAME_GLOBAL_INT, mav.MAV_CMD_NAV_WAYPOINT, 0, 1, 0, 0, 0, 0, 470000000, 80000000, 500.0, 0
    )
    h.settle()
    assert h.link.stats["mission_unexpected_item"] == 1


def test_silent_gcs_gets_retries_then_cancel(h):
    """timeout 0.2 s, 2 retries: the first request is repeated twice, then the upload is cancelled."""
    h.drain()
    h.gcs.mav.mission_count_send(SYSID, 1, 3, mav.MAV_MISSION_TYPE_MISSION)
    requests = 0
    while (m := h.recv(["MISSION_REQUEST_INT", "MISSION_ACK"], timeout=1.5)) is not None:
        if m.get_type() == "MISSION_ACK":
            break
        requests += 1
    assert requests == 3 and m.type == mav.MAV_MISSION_OPERATION_CANCELLED
    assert h.link.stats["mission_retry"] == 2 and h.link.stats["mission_timeout"] == 1
    assert not h.link.mission.uploading


def test_gcs_can_cancel_its_upload(h):
    h.gcs.mav.mission_count_send(SYSID, 1, 3, mav.MAV_MISSION_TYPE_MISSION)
    assert h.recv("MISSION_REQUEST_INT").seq == 0
    assert h.link.mission.uploading
    h.gcs.mav.mission_ack_send(SYSID, 1, mav.MAV_MISSION_OPERATION_CANCELLED, mav.MAV_MISSION_TYPE_MISSION)
    h.settle()
    assert not h.link.mission.uploading


def test_unsupported_frame_is_refused(h):
    ack = upload(h, WAYPOINTS, frame=mav.MAV_FRAME_LOCAL_NED)
    assert ack.type == mav.MAV_MISSION_UNSUPPORTED_FRAME


# -- commands ----------------------------------------------------------------------------------
def test_arm_and_mode_commands_are_acknowledged(h):
    g = h.gcs.mav
    g.command_long_send(SYSID, 1, mav.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
    ack = h.recv("COMMAND_ACK")
    assert (ack.command, ack.result) == (mav.MAV_CMD_COMPONENT_ARM_DISARM, mav.MAV_RESULT_ACCEPTED)
    assert (ack.target_system, ack.target_component) == (255, 190)
    custom = mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    g.command_long_send(SYSID, 1, mav.MAV_CMD_DO_SET_MODE, 0, custom, MODES["GUIDED"].custom_mode, 0, 0, 0, 0, 0)
    ack = h.recv("COMMAND_ACK")
    assert (ack.command, ack.result) == (mav.MAV_CMD_DO_SET_MODE, mav.MAV_RESULT_ACCEPTED)
    g.set_mode_send(SYSID, custom, MODES["HOLD"].custom_mode)
    assert h.recv("COMMAND_ACK").result == mav.MAV_RESULT_ACCEPTED
    g.command_long_send(SYSID, 1, mav.MAV_CMD_DO_SET_MODE, 0, custom, 99, 0, 0, 0, 0, 0)
    assert h.recv("COMMAND_ACK").result == mav.MAV_RESULT_DENIED
    g.command_long_send(SYSID, 1, mav.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, 21196, 0, 0, 0, 0, 0)
    assert h.recv("COMMAND_ACK").result == mav.MAV_RESULT_ACCEPTED
    g.command_long_send(SYSID, 1, mav.MAV_CMD_DO_REPOSITION, 0, 0, 0, 0, 0, 0, 0, 0)
    assert h.recv("COMMAND_ACK").result == mav.MAV_RESULT_UNSUPPORTED
    h.settle()
    assert h.commands == [Arm(True), SetMode("GUIDED"), SetMode("HOLD"), Arm(False, force=True)]
    assert h.link.stats["unknown_mode"] == 1


def test_position_target_respects_type_mask(h):
    ignore_z_accel_yawrate = (
        mav.POSITION_TARGET_TYPEMASK_Z_IGNORE | 0b111 << 6 | mav.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
    )
    h.gcs.mav.set_position_target_local_ned_send(
        1234,
        SYSID,
        1,
        mav.MAV_FRAME_LOCAL_NED,
        ignore_z_accel_yawrate,
        10.0,
        20.0,
        -30.0,
        1.0,
        2.0,
        3.0,
        0,
        0,
        0,
        0.5,
        0.1,
    )
    velocity_only = (
        0b111 | 0b111 << 6 | mav.POSITION_TARGET_TYPEMASK_YAW_IGNORE | mav.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
    )
    h.gcs.mav.set_position_target_local_ned_send(
        1300, SYSID, 1, mav.MAV_FRAME_LOCAL_NED, velocity_only, 0, 0, 0, 4.0, 5.0, 6.0, 0, 0, 0, 0, 0
    )
    h.gcs.mav.set_position_target_local_ned_send(
        1400, SYSID, 1, mav.MAV_FRAME_BODY_NED, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0
    )
    h.settle(0.2)
    a, b = h.commands
    assert isinstance(a, PositionTarget) and a.t_boot_ms == 1234
    np.testing.assert_array_equal(a.pos_ned, [10.0, 20.0, np.nan])
    np.testing.assert_array_equal(a.vel_ned, [1.0, 2.0, 3.0])
    assert a.yaw == pytest.approx(0.5) and a.yaw_rate is None
    assert b.pos_ned is None and b.yaw is None and b.yaw_rate is None
    np.testing.assert_array_equal(b.vel_ned, [4.0, 5.0, 6.0])
    assert h.link.stats["unsupported_frame"] == 1


def test_param_request_list_is_answered(h):
    h.gcs.mav.param_request_list_send(SYSID, 1)
    params = {}
    while (m := h.recv("PARAM_VALUE", timeout=1.0)) is not None:
        params[m.param_id] = m
        if len(params) == m.param_count:
            break
    assert params["SYSID_THISMAV"].param_value == SYSID
    assert sorted(p.param_index for p in params.values()) == list(range(len(params)))


# -- hostile input -----------------------------------------------------------------------------
def test_garbage_bad_crc_and_wrong_target_are_survived_and_counted(h):
    sock = h.gcs.port  # the GCS's own socket, so replies would reach it
    addr = h.link.local_address
    sock.sendto(b"\x00garbage that is not MAVLink at all", addr)
    sock.sendto(random.Random(9).randbytes(300), addr)  # may hold frame starts: counted, whatever kind
    sock.sendto(b"", addr)
    h.settle(0.1)
    before = dict(h.link.stats)
    encoder = mav.MAVLink(None, 255, 190)
    good = encoder.command_long_encode(SYSID, 1, mav.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0).pack(encoder)
    bad = bytearray(good)
    bad[-1] ^= 0x5A
    sock.sendto(bytes(bad), addr)
    sock.sendto(good[: len(good) // 2], addr)
    other = encoder.command_long_encode(SYSID + 1, 1, mav.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
    sock.sendto(other.pack(encoder), addr)
    h.settle(0.2)
    stats = h.link.stats
    assert before["garbage"] >= 2
    assert stats["bad_crc"] == before.get("bad_crc", 0) + 1
    assert stats["truncated"] == before.get("truncated", 0) + 1
    assert stats["wrong_target"] == 1
    assert h.commands == []
    # still works afterwards
    sock.sendto(good, addr)
    assert h.recv("COMMAND_ACK").result == mav.MAV_RESULT_ACCEPTED
    assert Arm(True) in h.commands
    # the comm error count reaches the GCS in SYS_STATUS
    h.drain()
    h.link.publish(9.0, make_state(9.0), 0, True, "AUTO", [], ORIGIN)
    assert h.recv("SYS_STATUS").errors_comm >= 3
    h.link.close()
    assert {lvl for lvl, text in h.events if "bad_crc" in text} == {"warning"}


def test_anomalies_are_summarised_at_most_once_per_second(h):
    h.events.clear()
    t0 = time.monotonic()
    for _ in range(20):  # 2,000 datagrams over ~2 s (in rounds the socket buffer holds)
        for _ in range(100):
            h.gcs.port.sendto(b"\x01\x02\x03", h.link.local_address)
        h.settle(0.1)
    elapsed = time.monotonic() - t0
    reports = [t for _, t in h.events if "garbage" in t]
    assert h.link.stats["garbage"] == 2000
    assert 1 <= len(reports) <= 1 + elapsed  # the first at once, then one per second at most
    h.link.close()  # what is pending is reported at the close
    reports = [t for _, t in h.events if "garbage" in t]
    assert sum(int(t.split("garbage ")[1].split(";")[0]) if "anomalies" in t else 1 for t in reports) == 2000
