"""A pymavlink GCS on loopback during a closed-loop run: telemetry, mission upload, garbage."""

import hashlib
import math
import os
import random
import socket
import threading
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mav

from sim.geodesy import GeoPoint, ned_to_geodetic
from sim.replay.runlog import RunLog
from sim.runner import run_scenario
from sim.scenario import parse_scenario

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.closed_loop
ORIGIN = GeoPoint(47.0, 8.0, 400.0)
TARGETS = np.array([[20.0, 0.0, -15.0], [20.0, 20.0, -15.0], [0.0, 20.0, -15.0]])  # NED [m]
# A wait's upper bound [s] (wall time), against a hang only: every wait ends as soon as its
# message arrives or the run is over; on a loaded machine a run can take tens of seconds to start.
WAIT_S = 300.0
# Sim time [s] an upload test may run: the GCS thread uploads when it gets to it (wall time; the
# run is paced at 4x and shares the GIL with it), so a loaded machine delivers the upload late.
# The run stops when the uploaded mission completes; the flight after the upload is bounded by
# UPLOADED_MISSION_S on the event times instead.
LATE_UPLOAD_ROOM_S = 1800.0
HOVER_HOLD = "1000 s"  # longer than any run: the hover itself never completes the mission
UPLOADED_MISSION_S = 30.0  # the 3 uploaded waypoints take about 17 s [s, sim time]


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Gcs(threading.Thread):
    """Waits for the vehicle, checks telemetry, uploads 3 waypoints, throws garbage at it.
    ``source_system``: the id it sends as (255 is the scenario's ground station); ``upload``
    False: it only introduces itself and listens. :meth:`join` tells it that the run is over: it
    reads what the vehicle sent until then and stops."""

    def __init__(self, port: int, source_system: int = 255, upload: bool = True, key: bytes | None = None):
        super().__init__(daemon=True)
        self.conn = mavutil.mavlink_connection(
            f"udpin:127.0.0.1:{port}", dialect="common", source_system=source_system, source_component=190
        )
        if key is not None:  # sign what it sends; first try an unsigned mode switch with the same ids
            self.conn.setup_signing(key, sign_outgoing=True)
        self.key = key
        self.upload = upload
        self.heartbeat = None
        self.positions = []
        self.ack = None
        self.error = None
        self.hold_off_s = 0.0
        self.run_over = threading.Event()

    def recv(self, kinds, timeout=WAIT_S):
        """The next message of a type in ``kinds``; None after ``timeout`` [s] or, once the run
        is over, when nothing more is queued."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            m = self.conn.recv_match(blocking=True, timeout=0.05)
            if m is None:
                if self.run_over.is_set():
                    return None
                continue
            if m.get_type() == "GLOBAL_POSITION_INT":
                self.positions.append(m)
            if m.get_type() in kinds:
                return m
        return None

    def run(self):
        try:
            self.heartbeat = self.recv({"HEARTBEAT"})
            self.conn.mav.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            self.recv({"GLOBAL_POSITION_INT"})
            time.sleep(self.hold_off_s)
            if not self.upload:
                return
            # garbage first: the run must survive it and still take the mission
            vehicle = next(iter(self.conn.clients))  # the address the vehicle sends from
            if self.key is not None:
                unsigned = mav.MAVLink(None, 255, 190)
                guided = unsigned.set_mode_encode(1, mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 3)
                self.conn.port.sendto(guided.pack(unsigned), vehicle)
            self.conn.port.sendto(b"\xfd\x05garbage-not-mavlink", vehicle)
            self.conn.port.sendto(bytes(range(256)), vehicle)
            lat, lon, alt = ned_to_geodetic(TARGETS, ORIGIN)
            self.conn.mav.mission_count_send(1, 1, 3, mav.MAV_MISSION_TYPE_MISSION)
            while (m := self.recv({"MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"})) is not None:
                if m.get_type() == "MISSION_ACK":
                    self.ack = m
                    break
                k = m.seq
                self.conn.mav.mission_item_int_send(
                    1,
                    1,
                    k,
                    mav.MAV_FRAME_GLOBAL_INT,
                    mav.MAV_CMD_NAV_WAYPOINT,
                    0,
                    1,
                    0,
                    0,
                    0,
                    math.nan,
                    round(lat[k] * 1e7),
                    round(lon[k] * 1e7),
                    float(alt[k]),
                    mav.MAV_MISSION_TYPE_MISSION,
                )
            while self.recv({"GLOBAL_POSITION_INT"}) is not None:  # to the end of the run
                pass
        except Exception as exc:  # noqa: BLE001 - reported by the test
            self.error = exc

    def join(self, timeout=WAIT_S):
        self.run_over.set()
        super().join(timeout)


def _upload_to_end_s(events: list[tuple[float, str]], end_t: float) -> float:
    """Sim time [s] from the upload event to the end of the run."""
    uploaded = [t for t, text in events if "mission uploaded" in text]
    assert len(uploaded) == 1, uploaded
    return end_t - uploaded[0]


def test_gcs_uploads_a_mission_that_the_vehicle_flies(fly, scenario_data):
    port = _free_port()
    data = scenario_data("quad_square_mission")
    data.update(
        duration=LATE_UPLOAD_ROOM_S,
        stop_when_complete=True,
        mavlink={"enabled": True, "base_port": port, "rate_hz": 5.0, "pace": 4.0},
    )
    v = data["vehicle"][0]
    v["mission"]["land"] = False
    v["mission"]["waypoints"] = [{"north": 0, "east": 0, "altitude": 415, "hold": HOVER_HOLD}]
    gcs = Gcs(port)
    gcs.hold_off_s = 2.0  # upload while the vehicle already holds at its first waypoint (the hold must end)
    gcs.start()
    run = fly(data, "mav")
    result, log = run.result, run.log
    gcs.join()
    assert not gcs.is_alive()
    assert gcs.error is None
    assert gcs.heartbeat is not None and gcs.heartbeat.get_srcSystem() == 1 and gcs.heartbeat.get_srcComponent() == 1
    assert gcs.heartbeat.type == mav.MAV_TYPE_QUADROTOR
    assert gcs.ack is not None and gcs.ack.type == mav.MAV_MISSION_ACCEPTED
    events = [text for _, text in log.events()]
    assert "quad: mission uploaded: 3 waypoints, mode AUTO" in events
    assert [e for e in events if "waypoint" in e and e.endswith("/3 reached")] == [
        f"quad: waypoint {k}/3 reached" for k in (1, 2, 3)
    ]
    assert result.status == "completed", (result.sim_time_s, log.events())
    assert 5.0 < _upload_to_end_s(log.events(), result.sim_time_s) < UPLOADED_MISSION_S
    assert any("mavlink" in e and "garbage" in e for e in events)
    # telemetry matched the vehicle: the last position report is near the last waypoint
    last = gcs.positions[-1]
    lat, lon, alt = ned_to_geodetic(TARGETS[-1], ORIGIN)
    assert abs(last.lat / 1e7 - lat) < 2e-5 and abs(last.lon / 1e7 - lon) < 2e-5
    assert abs(last.alt / 1e3 - alt) < 1.0


def _hover_scenario(port: int, duration: float = 20.0) -> dict:
    """The quadrotor hovering at 15 m for longer than any run (so that only a command could
    move it, and only an uploaded mission can complete the run)."""
    data = tomllib.loads((ROOT / "scenarios" / "quad_square_mission.toml").read_text())
    data.update(
        duration=duration,
        stop_when_complete=True,
        mavlink={"enabled": True, "base_port": port, "rate_hz": 5.0, "pace": 4.0},
    )
    v = data["vehicle"][0]
    v["mission"]["land"] = False
    v["mission"]["waypoints"] = [{"north": 0, "east": 0, "altitude": 415, "hold": HOVER_HOLD}]
    return data


def _fly(tmp_path, name: str, peer: threading.Thread) -> RunLog:
    port = peer.port
    peer.start()
    path = tmp_path / f"{name}.mcap"
    run_scenario(parse_scenario(_hover_scenario(port), name), path)
    peer.join()
    assert not peer.is_alive()
    return RunLog(path)


def _truth(log: RunLog) -> list:
    return log.topic("/quad/truth/state").messages


class _Listener(Gcs):
    def __init__(self, port: int, **kw):
        super().__init__(port, **kw)
        self.port = port


@pytest.fixture(scope="module")
def undisturbed(tmp_path_factory) -> list:
    """Truth states of the hover with the ground station only listening."""
    port = _free_port()
    return _truth(_fly(tmp_path_factory.mktemp("base"), "base", _Listener(port, upload=False)))


def test_upload_from_another_system_id_is_refused_and_the_flight_unchanged(tmp_path, undisturbed):
    port = _free_port()
    gcs = _Listener(port, source_system=42)
    log = _fly(tmp_path, "foreign", gcs)
    assert gcs.error is None
    assert gcs.ack is not None and gcs.ack.type == mav.MAV_MISSION_DENIED
    assert not any("mission uploaded" in text for _, text in log.events())
    assert any("unauthorised" in text for _, text in log.events())
    assert _truth(log) == undisturbed


class _Fuzzer(threading.Thread):
    """The ground station introduces itself and listens; meanwhile senders with other system ids
    throw mutated control frames (mode switches, arming, mission uploads, position targets under
    ground) and random bytes at the vehicle until the run ends."""

    def __init__(self, port: int, seed: int, senders: tuple[int, ...] = (1, 2, 42, 200, 254)):
        super().__init__(daemon=True)
        self.port = port
        self.senders = senders
        self.gcs = _Listener(port, upload=False)
        self.rng = random.Random(seed)
        self.sent = 0
        self.stop = threading.Event()

    def _frame(self) -> bytes:
        rng = self.rng
        enc = mav.MAVLink(None, rng.choice(self.senders), rng.choice([0, 1, 190]))
        msg = rng.choice(
            [
                enc.set_mode_encode(1, mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 3),
                enc.command_long_encode(1, 1, mav.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, 21196, 0, 0, 0, 0, 0),
                enc.mission_count_encode(1, 1, 1, mav.MAV_MISSION_TYPE_MISSION),
                enc.mission_item_int_encode(
                    1, 1, 0, mav.MAV_FRAME_GLOBAL_INT, 16, 0, 1, 0, 0, 0, 0, 470000000, 80000000, 100.0, 0
                ),
                enc.set_position_target_local_ned_encode(
                    0, 1, 1, mav.MAV_FRAME_LOCAL_NED, 0b110111111000, 0, 0, 300, 0, 0, 0, 0, 0, 0, 0, 0
                ),
                enc.mission_clear_all_encode(1, 1, 0),
            ]
        )
        buf = bytearray(msg.pack(enc))
        for _ in range(rng.randint(0, 2)):
            buf[rng.randrange(len(buf))] ^= rng.randint(1, 255)
        return bytes(buf) if rng.random() < 0.9 else rng.randbytes(rng.randint(0, 400))

    def run(self):
        self.gcs.start()
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            while not self.gcs.conn.clients and not self.stop.is_set():
                time.sleep(0.01)
            vehicle = next(iter(self.gcs.conn.clients), None)
            while vehicle is not None and not self.stop.wait(0.002):
                s.sendto(self._frame(), vehicle)
                self.sent += 1

    def join(self, timeout=WAIT_S):
        self.stop.set()
        super().join(timeout)
        self.gcs.join(timeout)


def test_fuzz_from_foreign_ids_does_not_change_the_flight(tmp_path, undisturbed):
    fuzzer = _Fuzzer(_free_port(), seed=3)
    start = time.monotonic()
    log = _fly(tmp_path, "fuzz", fuzzer)
    wall_s = time.monotonic() - start
    assert fuzzer.sent > 200
    assert _truth(log) == undisturbed
    mav_events = [text for _, text in log.events() if "mavlink" in text]
    # anomalies summarised at most once per second of wall time, plus one line per peer seen
    peers = len(fuzzer.senders) * 3 + 1  # the fuzzer's (system, component) pairs and the ground station
    assert len(mav_events) <= math.ceil(wall_s) + 1 + peers + 1, (wall_s, mav_events)


def test_with_signing_the_signed_gcs_is_obeyed_and_unsigned_commands_refused(tmp_path):
    port = _free_port()
    (tmp_path / "key").write_text("a passphrase")
    data = _hover_scenario(port, duration=LATE_UPLOAD_ROOM_S)
    data["mavlink"]["signing_key_file"] = str(tmp_path / "key")
    gcs = Gcs(port, key=hashlib.sha256(b"a passphrase").digest())
    gcs.start()
    result = run_scenario(parse_scenario(data, "signed"), tmp_path / "signed.mcap")
    gcs.join()
    assert not gcs.is_alive()
    assert gcs.error is None and gcs.heartbeat is not None and gcs.heartbeat.get_signed()
    assert gcs.ack is not None and gcs.ack.type == mav.MAV_MISSION_ACCEPTED
    timed = RunLog(tmp_path / "signed.mcap").events()
    events = [text for _, text in timed]
    assert "quad: mission uploaded: 3 waypoints, mode AUTO" in events
    assert not any("mode GUIDED" in e for e in events)  # the unsigned SET_MODE was dropped
    assert any("bad_signature" in e for e in events)
    assert result.status == "completed", (result.sim_time_s, timed)
    assert 5.0 < _upload_to_end_s(timed, result.sim_time_s) < UPLOADED_MISSION_S


def test_fuzz_from_the_ground_station_keeps_the_vehicle_in_its_envelope(tmp_path):
    """The same traffic with the ground station's own ids (after its heartbeat): mode switches
    and arming may act, but nothing under the ground is accepted and the run completes."""
    fuzzer = _Fuzzer(_free_port(), seed=4, senders=(255,))
    log = _fly(tmp_path, "gcs_fuzz", fuzzer)
    assert fuzzer.sent > 200
    events = [text for _, text in log.events()]
    assert not any("mission uploaded" in e or "position target:" in e for e in events)
    assert any("mission_invalid_item" in e or "position_target_refused" in e for e in events)
    up = -log.topic("/quad/truth/state")["pos_ned"][:, 2]
    assert up.min() > -0.5 and log.metadata["result"]["status"] != "failed"
