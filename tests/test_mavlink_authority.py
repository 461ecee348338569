"""The MAVLink link obeys only its ground station and keeps the vehicle in its envelope:
foreign senders, senders before their heartbeat, unsigned frames with signing on, mission items
and targets under ground / too high / too far / in a keep-out fence, oversized datagrams, and a
hypothesis fuzz of random frames from foreign and authorised ids."""

import hashlib
import math
import os
import struct
import time
import tomllib
from pathlib import Path

os.environ.setdefault("MAVLINK20", "1")

import numpy as np
import pytest
import tomli_w
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mav
from shapely.geometry import Polygon
from test_mavlink_bridge import ORIGIN, SYSID, WAYPOINTS, Harness, free_port, upload

from sim.core.threats import Geofence
from sim.geodesy import geodetic_to_ned, ned_to_geodetic
from sim.mavlink import LinkConfig, MissionUpload, PositionTarget, SetMode, VehicleLink
from sim.mavlink.envelope import Envelope
from sim.mavlink.signing import SigningKeyError, load_key

KEEP_OUT = Geofence("tower", Polygon([(-1200, -100), (-900, -100), (-900, 100), (-1200, 100)]), 0.0, 400.0, False)
ENVELOPE = Envelope(max_height_m=2000.0, max_range_m=20_000.0, fences=(KEEP_OUT,))
CUSTOM = mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED


@pytest.fixture
def h():
    harness = Harness(envelope=ENVELOPE, mission_timeout_s=0.2, mission_retries=1)
    yield harness
    harness.close()


def foreign(h, sysid=42, compid=190):
    """An encoder for another sender on the GCS's socket (replies come back to the GCS)."""
    enc = mav.MAVLink(None, sysid, compid)

    def send(msg):
        h.gcs.port.sendto(msg.pack(enc), h.link.local_address)

    return enc, send


def test_foreign_sender_is_refused_with_protocol_codes(h):
    enc, send = foreign(h)
    send(enc.heartbeat_encode(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0))
    send(enc.command_long_encode(SYSID, 1, mav.MAV_CMD_DO_SET_MODE, 0, CUSTOM, 3, 0, 0, 0, 0, 0))
    ack = h.recv("COMMAND_ACK")
    assert (ack.command, ack.result, ack.target_system) == (mav.MAV_CMD_DO_SET_MODE, mav.MAV_RESULT_DENIED, 42)
    send(enc.set_mode_encode(SYSID, CUSTOM, 3))
    assert h.recv("COMMAND_ACK").result == mav.MAV_RESULT_DENIED
    send(enc.mission_count_encode(SYSID, 1, 2, mav.MAV_MISSION_TYPE_MISSION))
    assert h.recv("MISSION_ACK").type == mav.MAV_MISSION_DENIED
    send(
        enc.set_position_target_local_ned_encode(
            0, SYSID, 1, mav.MAV_FRAME_LOCAL_NED, 0b110111111000, 0, 0, 300, 0, 0, 0, 0, 0, 0, 0, 0
        )
    )
    h.settle()
    assert h.commands == [] and not h.link.mission.uploading
    assert h.link.stats["unauthorised"] == 4
    # the ground station itself is still obeyed
    h.gcs.mav.set_mode_send(SYSID, CUSTOM, 3)
    assert h.recv("COMMAND_ACK").result == mav.MAV_RESULT_ACCEPTED
    assert h.commands == [SetMode("GUIDED")]


def test_ground_station_is_obeyed_only_after_its_heartbeat():
    h = Harness(heartbeat=False)
    try:
        h.gcs.mav.set_mode_send(SYSID, CUSTOM, 3)
        assert h.recv("COMMAND_ACK").result == mav.MAV_RESULT_DENIED
        assert h.link.stats["unauthorised"] == 1 and "before its heartbeat" in h.events[-1][1]
        h.gcs.mav.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        h.gcs.mav.set_mode_send(SYSID, CUSTOM, 3)
        assert h.recv("COMMAND_ACK").result == mav.MAV_RESULT_ACCEPTED
        assert h.commands == [SetMode("GUIDED")]
    finally:
        h.close()


def test_configured_component_is_required():
    h = Harness(gcs_component_id=191)  # the harness GCS is 255/190
    try:
        assert not h.link.gcs_heard
        h.gcs.mav.set_mode_send(SYSID, CUSTOM, 3)
        assert h.recv("COMMAND_ACK").result == mav.MAV_RESULT_DENIED
    finally:
        h.close()


def _item_ack(h, lat, lon, alt):
    return upload(h, [*WAYPOINTS[:1], (lat, lon, alt)]).type


@pytest.mark.parametrize(
    ("ned", "result"),
    [
        ((100.0, 0.0, 300.0), mav.MAV_MISSION_INVALID_PARAM7),  # 300 m below the ground
        ((100.0, 0.0, -100_000.0), mav.MAV_MISSION_INVALID_PARAM7),  # 100 km up
        ((30_000.0, 0.0, -100.0), mav.MAV_MISSION_INVALID_PARAM5_X),  # beyond max_range
        ((-1000.0, 0.0, -100.0), mav.MAV_MISSION_DENIED),  # inside the keep-out fence
    ],
)
def test_mission_items_outside_the_envelope_are_refused(h, ned, result):
    lat, lon, alt = (float(x) for x in ned_to_geodetic(np.array(ned), ORIGIN))
    assert _item_ack(h, lat, lon, alt) == result
    h.settle()
    assert not [c for c in h.commands if isinstance(c, MissionUpload)]
    assert h.link.stats["mission_invalid_item"] == 1


def _float_item_ack(h, lat, lon, alt):
    """Upload of one MISSION_ITEM (float coordinates, so any value fits the wire)."""
    h.gcs.mav.mission_count_send(SYSID, 1, 1, mav.MAV_MISSION_TYPE_MISSION)
    assert h.recv(["MISSION_REQUEST_INT", "MISSION_REQUEST"]).seq == 0
    h.gcs.mav.mission_item_send(
        SYSID, 1, 0, mav.MAV_FRAME_GLOBAL, mav.MAV_CMD_NAV_WAYPOINT, 0, 1, 0, 0, 0, 0, lat, lon, alt, 0
    )
    return h.recv("MISSION_ACK").type


def test_absurd_coordinates_are_refused(h):
    assert _float_item_ack(h, 1e30, 8.0, 500.0) == mav.MAV_MISSION_INVALID_PARAM5_X
    assert _float_item_ack(h, 47.0, 8.0, 1e30) == mav.MAV_MISSION_INVALID_PARAM7
    assert _float_item_ack(h, 47.0, 8.0, -1e30) == mav.MAV_MISSION_INVALID_PARAM7
    # over the keep-out fence's top is fine
    lat, lon, alt = (float(x) for x in ned_to_geodetic(np.array([-1000.0, 0.0, -450.0]), ORIGIN))
    assert _item_ack(h, lat, lon, alt) == mav.MAV_MISSION_ACCEPTED


def test_position_targets_outside_the_envelope_are_dropped(h):
    full = 0b110111111000  # position only
    for z in (300.0, -5000.0):  # under ground, above max_height
        h.gcs.mav.set_position_target_local_ned_send(
            0, SYSID, 1, mav.MAV_FRAME_LOCAL_NED, full, 10, 0, z, 0, 0, 0, 0, 0, 0, 0, 0
        )
    h.gcs.mav.set_position_target_local_ned_send(
        0, SYSID, 1, mav.MAV_FRAME_LOCAL_NED, full, -1000, 0, -50, 0, 0, 0, 0, 0, 0, 0, 0
    )
    h.gcs.mav.set_position_target_local_ned_send(
        0, SYSID, 1, mav.MAV_FRAME_LOCAL_NED, full, 10, 0, -50, 0, 0, 0, 0, 0, 0, 0, 0
    )
    h.settle(0.2)
    assert h.link.stats["position_target_refused"] == 3
    (target,) = h.commands
    np.testing.assert_array_equal(target.pos_ned, [10.0, 0.0, -50.0])


def test_non_loopback_gcs_needs_an_explicit_bind_and_loopback_is_the_default():
    with pytest.raises(ValueError, match="not on loopback: set bind_host"):
        VehicleLink(LinkConfig(system_id=1, gcs_host="192.0.2.1"))
    with pytest.raises(ValueError, match="does not resolve"):
        VehicleLink(LinkConfig(system_id=1, gcs_host="no-such-host.invalid"))
    with VehicleLink(LinkConfig(system_id=1, gcs_port=free_port())) as link:
        assert link.local_address[0] == "127.0.0.1"
    with VehicleLink(LinkConfig(system_id=1, gcs_host="192.0.2.1", bind_host="0.0.0.0")) as link:
        assert link.local_address[0] == "0.0.0.0"


def test_oversize_datagrams_are_dropped_unparsed(h):
    enc = mav.MAVLink(None, 255, 190)
    frame = enc.set_mode_encode(SYSID, CUSTOM, 3).pack(enc)
    h.gcs.port.sendto(frame * 200, h.link.local_address)  # valid frames, but 3 KiB in one datagram
    h.settle()
    assert h.link.stats["oversize"] == 1 and h.commands == []


def test_receive_work_is_bounded_per_poll(h):
    enc = mav.MAVLink(None, 255, 190)
    for _ in range(100):
        h.gcs.port.sendto(enc.set_mode_encode(SYSID, CUSTOM, 3).pack(enc), h.link.local_address)
    time.sleep(0.05)
    assert len(h.link.poll()) == 32  # the rest waits for the next tick
    assert len(h.link.poll()) == 32


# -- signing -------------------------------------------------------------------------------------
def test_signing_key_comes_from_a_passphrase_file(tmp_path):
    f = tmp_path / "key"
    f.write_text("correct horse battery staple\n")
    assert load_key(f) == hashlib.sha256(b"correct horse battery staple").digest()
    with pytest.raises(SigningKeyError, match="empty"):
        (tmp_path / "empty").write_text("  \n")
        load_key(tmp_path / "empty")
    with pytest.raises(SigningKeyError, match="not a regular file"):
        load_key(tmp_path)
    with pytest.raises(SigningKeyError, match="cannot read"):
        load_key(tmp_path / "missing")
    assert "signing_key" not in repr(LinkConfig(system_id=1, signing_key=bytes(32))).split("signing_key=")[1:]


KEY = hashlib.sha256(b"test passphrase").digest()


def test_with_signing_on_unsigned_and_wrongly_signed_commands_are_refused():
    h = Harness(heartbeat=False, signing_key=KEY, gcs_key=KEY)
    try:
        assert h.first_heartbeat.get_signed()  # the vehicle signs what it sends
        h.gcs.mav.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        h.settle(0.05)
        assert h.link.gcs_heard
        unsigned = mav.MAVLink(None, 255, 190)  # same ids as the GCS, no key
        h.gcs.port.sendto(unsigned.set_mode_encode(SYSID, CUSTOM, 3).pack(unsigned), h.link.local_address)
        wrong = mav.MAVLink(None, 255, 190)
        wrong.signing.secret_key, wrong.signing.sign_outgoing = hashlib.sha256(b"guess").digest(), True
        wrong.signing.timestamp = 2**47  # a forged far-future timestamp must not lock the GCS out
        h.gcs.port.sendto(wrong.set_mode_encode(SYSID, CUSTOM, 3).pack(wrong), h.link.local_address)
        h.settle(0.1)
        assert h.commands == [] and h.link.stats["bad_signature"] == 2
        h.gcs.mav.set_mode_send(SYSID, CUSTOM, 3)  # signed by the GCS
        assert h.recv("COMMAND_ACK").result == mav.MAV_RESULT_ACCEPTED
        assert h.commands == [SetMode("GUIDED")]
    finally:
        h.close()


# -- fuzz ----------------------------------------------------------------------------------------
_TYPES = [cls for _, cls in sorted(mav.mavlink_map.items())]
_CONTROL = [
    getattr(mav, f"MAVLink_{name}_message")
    for name in (
        "command_long",
        "command_int",
        "set_mode",
        "set_position_target_local_ned",
        "mission_count",
        "mission_item_int",
        "mission_item",
        "mission_clear_all",
        "heartbeat",
    )
]
_FUZZ_HARNESS: dict[str, Harness] = {}


def _harness() -> Harness:
    """One link for all fuzz examples (a fresh one per example would cost a socket pair each)."""
    if "h" not in _FUZZ_HARNESS:
        _FUZZ_HARNESS["h"] = Harness(envelope=ENVELOPE, mission_timeout_s=0.05, mission_retries=0)
    return _FUZZ_HARNESS["h"]


_PLAUSIBLE = {
    "target_system": [SYSID, 0],
    "target_component": [1, 0],
    "seq": [0, 1, 2],
    "count": [1, 2, 3],
    "mission_type": [mav.MAV_MISSION_TYPE_MISSION],
    "frame": [mav.MAV_FRAME_GLOBAL_INT, mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, mav.MAV_FRAME_GLOBAL],
    "coordinate_frame": [mav.MAV_FRAME_LOCAL_NED],
    "command": [mav.MAV_CMD_NAV_WAYPOINT, mav.MAV_CMD_DO_SET_MODE, mav.MAV_CMD_COMPONENT_ARM_DISARM],
    "base_mode": [CUSTOM],
    "custom_mode": [0, 1, 2, 3],
    "type_mask": [0b110111111000, 0b110111000111, 0],
    "param1": [0.0, 1.0, float(CUSTOM)],
    "param2": [0.0, 3.0],
    "x": [47.0, 470_100_000, -1000.0, 10.0, 1e30, math.nan],
    "y": [8.0, 80_000_000, 0.0, 10.0, -1e30],
    "z": [500.0, -50.0, 300.0, 1e5, math.inf],
}


def _scalar_slots(cls) -> dict[str, int]:
    """Position of each scalar field in the unpacked wire tuple (arrays take one slot per
    element, char arrays one slot)."""
    slots, k = {}, 0
    for name, alen in zip(cls.ordered_fieldnames, cls.array_lengths, strict=True):  # both in wire order
        char = cls.fieldtypes[cls.fieldnames.index(name)] == "char"
        if not alen:
            slots[name] = k
        k += alen if alen and not char else 1
    return slots


@st.composite
def frames(draw, sysid):
    """A frame of a random common-dialect message (half of them one that could change the
    vehicle) with random field values, often replaced by plausible ones, packed with a valid CRC
    and optionally mutated by byte flips, cuts or repeats."""
    cls = draw(st.one_of(st.sampled_from(_CONTROL), st.sampled_from(_TYPES)))
    enc = mav.MAVLink(None, sysid, draw(st.sampled_from([190, 0, 1, 250])))
    payload = draw(st.binary(min_size=cls.unpacker.size, max_size=cls.unpacker.size))
    values = list(cls.unpacker.unpack(payload))
    for name, k in _scalar_slots(cls).items():
        if name in _PLAUSIBLE and draw(st.booleans()):
            values[k] = draw(st.sampled_from(_PLAUSIBLE[name]))
            try:
                payload = cls.unpacker.pack(*values)
            except struct.error:  # a plausible value of another type than this field's
                values = list(cls.unpacker.unpack(payload))
    buf = bytearray(mav.MAVLink_message(cls.id, cls.msgname)._pack(enc, cls.crc_extra, payload))
    for _ in range(draw(st.integers(0, 2))):
        op = draw(st.sampled_from(["flip", "cut", "dup"]))
        if op == "flip" and buf:
            i = draw(st.integers(0, len(buf) - 1))
            buf[i] ^= draw(st.integers(1, 255))
        elif op == "cut" and buf:
            buf = buf[: draw(st.integers(0, len(buf)))]
        else:
            buf = buf + buf
    return bytes(buf)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.sampled_from([1, 42, 254, 0]).flatmap(frames), min_size=1, max_size=8))
def test_fuzz_from_foreign_ids_changes_nothing(datagrams):
    h = _harness()
    h.commands.clear()
    for d in datagrams:
        h.gcs.port.sendto(d, h.link.local_address)
    h.settle(0.01)
    assert h.commands == []
    assert not h.link.mission.uploading or h.link.mission._upload.src[0] == 255


@settings(max_examples=200, deadline=None)
@given(st.lists(frames(255), min_size=1, max_size=8))
def test_fuzz_from_the_ground_station_stays_in_the_envelope(datagrams):
    h = _harness()
    h.commands.clear()
    for d in datagrams:
        h.gcs.port.sendto(d, h.link.local_address)
    h.settle(0.01)
    for c in h.commands:
        if isinstance(c, MissionUpload):
            for wp in c.waypoints:
                assert ENVELOPE.check(geodetic_to_ned(*wp, ORIGIN)) is None
        if isinstance(c, PositionTarget) and c.pos_ned is not None and not np.isnan(c.pos_ned).any():
            assert ENVELOPE.check(c.pos_ned) is None
        if isinstance(c, PositionTarget):
            assert all(x is None or math.isfinite(x) for x in (c.yaw, c.yaw_rate))


# -- scenario wiring -----------------------------------------------------------------------------
def test_scenario_mavlink_settings_reach_every_link(tmp_path):
    from types import SimpleNamespace

    from sim.mavlink.session import MavlinkSession
    from sim.scenario import Mavlink

    (tmp_path / "key").write_text("s3cret")
    port = free_port()
    cfg = Mavlink(
        enabled=True,
        gcs_host="localhost",
        base_port=port,
        rate_hz=7.0,
        pace=3.0,
        gcs_system_id=200,
        gcs_component_id=7,
        bind_host="127.0.0.1",
        signing_key_file=tmp_path / "key",
        max_height=300.0,
        max_range=5000.0,
    )
    quad = SimpleNamespace(
        name="q", airframe=SimpleNamespace(kind="multirotor"), mission=SimpleNamespace(waypoints=np.zeros((1, 3)))
    )
    haps = SimpleNamespace(name="h", airframe=SimpleNamespace(kind="fixed_wing"), mission=quad.mission)
    session = MavlinkSession(cfg, [quad, haps], ORIGIN, SimpleNamespace(event=lambda *a, **k: None), (KEEP_OUT,))
    try:
        assert session.pacer is not None and session.pacer.speed == 3.0
        for k, link in enumerate(session.links):
            c = link.config
            assert (c.gcs_host, c.gcs_port, c.rate_hz) == ("localhost", port + k, 7.0)
            assert (c.gcs_system_id, c.gcs_component_id, c.bind_host) == (200, 7, "127.0.0.1")
            assert c.signing_key == hashlib.sha256(b"s3cret").digest()
            assert link.envelope == Envelope(300.0, 5000.0, (KEEP_OUT,))
    finally:
        session.close()
    default = MavlinkSession(Mavlink(base_port=free_port(), pace=0.0), [quad, haps], ORIGIN, SimpleNamespace(), ())
    try:
        assert default.pacer is None  # pace 0: sim time, no waiting
        assert [(lk.envelope.max_height_m, lk.envelope.max_range_m) for lk in default.links] == [
            (1000.0, 20_000.0),
            (25_000.0, 500_000.0),
        ]
        assert all(lk.config.signing_key is None and lk.config.gcs_component_id is None for lk in default.links)
    finally:
        default.close()


def test_cli_signing_key_option(tmp_path, capsys):
    from sim.cli import _with_signing_key, main
    from sim.scenario import ScenarioError, parse_scenario

    data = tomllib.loads((Path(__file__).resolve().parents[1] / "scenarios" / "quad_hover_offset.toml").read_text())
    plain = parse_scenario(data, "s")
    with pytest.raises(ScenarioError, match="does not enable MAVLink"):
        _with_signing_key(plain, str(tmp_path / "key"))
    enabled = parse_scenario({**data, "mavlink": {"enabled": True}}, "s")
    (tmp_path / "key").write_text("pass")
    assert _with_signing_key(enabled, str(tmp_path / "key")).mavlink.signing_key_file == tmp_path / "key"
    f = tmp_path / "s.toml"
    f.write_text(tomli_w.dumps({**data, "mavlink": {"enabled": True}}))
    assert main(["run", str(f), "-q", "--mavlink-key", str(tmp_path / "missing")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "cannot read the MAVLink signing key" in err


def test_signing_key_file_is_relative_to_the_scenario_file(tmp_path):
    from sim.scenario import load_scenario

    data = tomllib.loads((Path(__file__).resolve().parents[1] / "scenarios" / "quad_hover_offset.toml").read_text())
    (tmp_path / "sub").mkdir()
    f = tmp_path / "sub" / "s.toml"
    f.write_text(tomli_w.dumps({**data, "mavlink": {"enabled": True, "signing_key_file": "key.txt"}}))
    scenario, _ = load_scenario(f)
    assert scenario.mavlink.signing_key_file == tmp_path / "sub" / "key.txt"
