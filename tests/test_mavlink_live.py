"""A pymavlink GCS on loopback during a closed-loop run: telemetry, mission upload, garbage."""

import math
import os
import socket
import threading
import time

import numpy as np
import pytest

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mav

from sim.geodesy import GeoPoint, ned_to_geodetic

pytestmark = pytest.mark.closed_loop
ORIGIN = GeoPoint(47.0, 8.0, 400.0)
TARGETS = np.array([[20.0, 0.0, -15.0], [20.0, 20.0, -15.0], [0.0, 20.0, -15.0]])  # NED [m]


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Gcs(threading.Thread):
    """Waits for the vehicle, checks telemetry, uploads 3 waypoints, throws garbage at it."""

    def __init__(self, port: int):
        super().__init__(daemon=True)
        self.conn = mavutil.mavlink_connection(
            f"udpin:127.0.0.1:{port}", dialect="common", source_system=255, source_component=190
        )
        self.heartbeat = None
        self.positions = []
        self.ack = None
        self.error = None
        self.hold_off_s = 0.0

    def recv(self, kinds, timeout=10.0):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            m = self.conn.recv_match(blocking=True, timeout=0.05)
            if m is None:
                continue
            if m.get_type() == "GLOBAL_POSITION_INT":
                self.positions.append(m)
            if m.get_type() in kinds:
                return m
        return None

    def run(self):
        try:
            self.heartbeat = self.recv({"HEARTBEAT"})
            self.recv({"GLOBAL_POSITION_INT"})
            time.sleep(self.hold_off_s)
            # garbage first: the run must survive it and still take the mission
            vehicle = next(iter(self.conn.clients))  # the address the vehicle sends from
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
            end = time.monotonic() + 30
            while time.monotonic() < end and self.recv({"GLOBAL_POSITION_INT"}, 1.0) is not None:
                pass
        except Exception as exc:  # noqa: BLE001 (any error in this thread is reported by the test)
            self.error = exc


def test_gcs_uploads_a_mission_that_the_vehicle_flies(fly, scenario_data):
    port = _free_port()
    data = scenario_data("quad_square_mission")
    data.update(
        duration=60.0,
        stop_when_complete=True,
        mavlink={"enabled": True, "base_port": port, "rate_hz": 5.0, "pace": 4.0},
    )
    v = data["vehicle"][0]
    v["mission"]["land"] = False
    v["mission"]["waypoints"] = [{"north": 0, "east": 0, "altitude": 415, "hold": "120 s"}]
    gcs = Gcs(port)
    gcs.hold_off_s = 2.0  # upload while the vehicle already holds at its first waypoint (the hold must end)
    gcs.start()
    run = fly(data, "mav")
    result, log = run.result, run.log
    gcs.join(timeout=5)
    assert gcs.error is None
    assert gcs.heartbeat is not None and gcs.heartbeat.get_srcSystem() == 1 and gcs.heartbeat.get_srcComponent() == 1
    assert gcs.heartbeat.type == mav.MAV_TYPE_QUADROTOR
    assert gcs.ack is not None and gcs.ack.type == mav.MAV_MISSION_ACCEPTED
    events = [text for _, text in log.events()]
    assert "quad: mission uploaded: 3 waypoints, mode AUTO" in events
    assert [e for e in events if "waypoint" in e and e.endswith("/3 reached")] == [
        f"quad: waypoint {k}/3 reached" for k in (1, 2, 3)
    ]
    assert result.status == "completed"
    assert any("mavlink" in e and "garbage" in e for e in events)
    # telemetry matched the vehicle: the last position report is near the last waypoint
    last = gcs.positions[-1]
    lat, lon, alt = ned_to_geodetic(TARGETS[-1], ORIGIN)
    assert abs(last.lat / 1e7 - lat) < 2e-5 and abs(last.lon / 1e7 - lon) < 2e-5
    assert abs(last.alt / 1e3 - alt) < 1.0
