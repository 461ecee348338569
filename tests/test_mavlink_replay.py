"""Replay of a run log to a pymavlink GCS at N x speed, and the wall-clock pacer."""

import math
import os
import socket
import threading
import time

os.environ.setdefault("MAVLINK20", "1")  # before pymavlink.mavutil picks a dialect

import numpy as np
import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mav

from sim.geodesy import GeoPoint, ned_to_geodetic
from sim.log_schemas import MISSION_STATUS, VEHICLE_STATE
from sim.mavlink.pacing import WallClockPacer
from sim.mavlink.replay import replay_to_gcs
from sim.mcap_log import McapLog
from sim.mcap_read import LogReadError

EPOCH = 1_782_021_600_000_000_000
ORIGIN = GeoPoint(47.0, 8.0, 100.0)
SCENARIO = """
name = "replay_unit"
seed = 1
duration = 10
[origin]
lat = 47.0
lon = 8.0
altitude = 100.0
[[vehicle]]
name = "haps"
aircraft = "haps"
initial = { altitude = 600.0, airspeed = 10.0 }
mission = { cruise_speed = 10.0, waypoints = [
    { north = 500.0, east = 0.0, altitude = 600.0 }, { north = 500.0, east = 500.0, altitude = 650.0 } ] }
[[vehicle]]
name = "quad"
aircraft = "quadrotor"
initial = { altitude = 150.0 }
mission = { cruise_speed = 5.0, waypoints = [ { north = 0.0, east = 50.0, altitude = 150.0 } ] }
"""
N_STATES, DT = 40, 0.1  # 4 s of sim time at 10 Hz


def write_log(path, scenario=SCENARIO):
    """Two vehicles flying north: 'haps' at 20 m/s, 500 m up; 'quad' at 5 m/s, 50 m up."""
    with McapLog(path, EPOCH) as log:
        log.metadata("run", {"epoch_ns": EPOCH, "scenario": "replay_unit"})
        if scenario:
            log.attach("scenario.toml", scenario.encode(), "application/toml")
        for k in range(N_STATES):
            t = k * DT
            for name, speed, up in (("haps", 20.0, 500.0), ("quad", 5.0, 50.0)):
                pos = np.array([speed * t, 0.0, -up])
                lat, lon, alt = ned_to_geodetic(pos, ORIGIN)
                log.write_json(
                    f"/{name}/truth/state",
                    t,
                    {
                        "t": t,
                        "pos_ned": pos.tolist(),
                        "vel_ned": [speed, 0.0, 0.0],
                        "euler": [0.0, 0.0, 0.0],
                        "rates_body": [0.0, 0.0, 0.0],
                        "alt_msl_m": float(alt),
                        "lat_deg": float(lat),
                        "lon_deg": float(lon),
                        "tas_mps": speed,
                        "eas_mps": speed,
                        "alpha_rad": 0.0,
                        "beta_rad": 0.0,
                    },
                    VEHICLE_STATE,
                )
                if k % 10 == 0:
                    log.write_json(
                        f"/{name}/mission/status",
                        t,
                        {"t": t, "next_waypoint": k // 10, "waypoints": 4, "complete": False},
                        MISSION_STATUS,
                    )


def two_gcs():
    """GCS connections on two consecutive free ports (retrying if the second is taken)."""
    for _ in range(20):
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        try:
            conns = [
                mavutil.mavlink_connection(
                    f"udpin:127.0.0.1:{p}", dialect="common", source_system=255, source_component=190
                )
                for p in (port, port + 1)
            ]
        except OSError:
            continue
        return port, conns
    pytest.skip("no two consecutive free UDP ports")


def collect(conn, until, messages, arrivals):
    """Read messages until ``until()`` and the socket is quiet; record GPI arrival times."""
    quiet_since = None
    while True:
        m = conn.recv_match(blocking=True, timeout=0.02)
        now = time.monotonic()
        if m is not None and m.get_type() != "BAD_DATA":
            messages.append(m)
            if m.get_type() == "GLOBAL_POSITION_INT":
                arrivals.append(now)
            quiet_since = None
        elif until():
            quiet_since = quiet_since or now
            if now - quiet_since > 0.2:
                return


def test_replay_reaches_gcs_at_n_times_speed(tmp_path):
    path = tmp_path / "run.mcap"
    write_log(path)
    port, (gcs_haps, gcs_quad) = two_gcs()
    speed = 4.0
    events, box = [], {}

    def run():
        box["result"] = replay_to_gcs(
            path, speed=speed, base_port=port, rate_hz=5.0, on_event=lambda text, level: events.append((level, text))
        )

    thread = threading.Thread(target=run)
    thread.start()
    try:
        haps_msgs, haps_arrivals, quad_msgs, quad_arrivals = [], [], [], []
        # the GCS asks for the mission once it has heard the vehicle
        first = gcs_haps.recv_match(type="HEARTBEAT", blocking=True, timeout=3)
        assert first is not None
        gcs_haps.mav.mission_request_list_send(1, 1, mav.MAV_MISSION_TYPE_MISSION)
        collect(gcs_haps, lambda: not thread.is_alive(), haps_msgs, haps_arrivals)
        collect(gcs_quad, lambda: True, quad_msgs, quad_arrivals)
    finally:
        thread.join(timeout=10)
        gcs_haps.close()
        gcs_quad.close()
    result = box["result"]
    assert result.complete and result.states == {"haps": N_STATES, "quad": N_STATES}

    def of(msgs, kind):
        return [m for m in msgs if m.get_type() == kind]

    # identity per vehicle: rank in name order -> system id and port
    assert {(m.get_srcSystem(), m.type) for m in [*of(haps_msgs, "HEARTBEAT"), first]} == {(1, mav.MAV_TYPE_FIXED_WING)}
    assert {(m.get_srcSystem(), m.type) for m in of(quad_msgs, "HEARTBEAT")} == {(2, mav.MAV_TYPE_QUADROTOR)}
    # 3.9 s of sim time at 5 Hz: t = 0, 0.2, ... 3.8
    gpi = of(haps_msgs, "GLOBAL_POSITION_INT")
    assert len(gpi) == 20 and len(of(quad_msgs, "GLOBAL_POSITION_INT")) == 20
    assert [m.time_boot_ms for m in gpi] == [200 * k for k in range(20)]
    lat, lon, _ = ned_to_geodetic(np.array([20.0 * 3.8, 0.0, -500.0]), ORIGIN)
    assert (gpi[-1].lat, gpi[-1].lon) == (round(float(lat) * 1e7), round(float(lon) * 1e7))
    assert gpi[-1].relative_alt == 500_000 and gpi[-1].vx == 2000
    assert of(haps_msgs, "MISSION_CURRENT")[-1].seq == 3
    assert of(haps_msgs, "MISSION_COUNT")[0].count == 2  # the scenario's mission
    # paced: 3.8 s of sim time over ~0.95 s of wall time (generous bounds, no flaky timing)
    expected = 3.8 / speed
    assert 0.7 * expected <= haps_arrivals[-1] - haps_arrivals[0] <= expected + 2.0
    assert result.wall_s >= 0.7 * 3.9 / speed
    assert not [e for e in events if e[0] in ("warning", "error")]


def test_replay_without_scenario_falls_back_and_can_stop(tmp_path):
    path = tmp_path / "bare.mcap"
    write_log(path, scenario="")
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sink:
        sink.bind(("127.0.0.1", 0))
        port = sink.getsockname()[1]
        events = []
        seen = []
        result = replay_to_gcs(
            path,
            speed=None,
            base_port=port,
            vehicles=["haps"],
            on_event=lambda text, level: events.append((level, text)),
            should_stop=lambda: seen.append(1) or len(seen) >= 15,
        )
        assert result.states == {"haps": 15} and not result.complete
        assert any(level == "warning" and "no scenario.toml" in text for level, text in events)
        sink.settimeout(1.0)
        parser = mav.MAVLink(None)
        home = None
        while home is None:
            for m in parser.parse_buffer(sink.recv(65535)) or ():
                if m.get_type() == "HOME_POSITION":
                    home = m
        # fallback origin altitude = alt MSL + D of the first state = the true origin's
        assert home.altitude == round(ORIGIN.alt_m * 1000)


def test_replay_of_damaged_log_is_a_clear_error(tmp_path):
    path = tmp_path / "cut.mcap"
    write_log(path)
    full = sum(replay_to_gcs(path, speed=None).states.values())
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])  # unfinished: replayed up to its last complete chunk
    assert sum(replay_to_gcs(path, speed=None).states.values()) < full
    path.write_bytes(b"not an MCAP" + data[100:200])
    with pytest.raises(LogReadError, match=r"cut\.mcap"):
        replay_to_gcs(path, speed=None)
    write_log(path)
    with pytest.raises(ValueError, match="no vehicle ghost"):
        replay_to_gcs(path, speed=None, vehicles=["ghost"])


# -- pacer ---------------------------------------------------------------------------------------
class FakeClock:
    def __init__(self):
        self.now = 100.0
        self.slept = []

    def __call__(self):
        return self.now

    def sleep(self, s):
        self.slept.append(s)
        self.now += s


def test_pacer_holds_sim_time_to_n_times_wall_time():
    c = FakeClock()
    p = WallClockPacer(speed=2.0, clock=c, sleep=c.sleep)
    assert p.pace(10.0) == 0.0  # anchors
    assert p.pace(11.0) == pytest.approx(0.5)
    c.now += 0.2  # the simulation itself took 0.2 s of the next 0.5 s
    assert p.pace(12.0) == pytest.approx(0.3)
    assert c.now == pytest.approx(101.0)


def test_pacer_does_not_burst_after_a_slow_stretch_and_reanchors_on_time_jumps():
    c = FakeClock()
    p = WallClockPacer(speed=1.0, max_lag_s=0.25, clock=c, sleep=c.sleep)
    p.pace(0.0)
    c.now += 5.0  # a 5 s stall
    assert p.pace(1.0) == 0.0  # 4 s behind: re-anchored ...
    assert p.pace(2.0) == pytest.approx(1.0)  # ... so the next second takes a second again
    assert p.pace(0.5) == 0.0  # time went back (replay restarted): new anchor, no sleep
    assert p.pace(1.0) == pytest.approx(0.5)
    with pytest.raises(ValueError):
        WallClockPacer(speed=0.0)
    assert math.isclose(sum(c.slept), 1.5)
