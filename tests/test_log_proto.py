"""Compact logs: the protobuf messages of sim/log_proto.py read back as the dicts their JSON
messages give (doubles bit-identical, NaN as None; measured sensor values as their float32
rounding), mirror the JSON Schemas field for field, and the LiDAR scan reads back bit-identical
from its compact form."""

import math

import numpy as np
import pytest
from shapely.geometry import box

from sim import log_proto
from sim import log_schemas as S
from sim.core.state import VehicleState
from sim.core.threats import PrismObstacle
from sim.mcap_log import LogWriteError, McapLog
from sim.mcap_read import iter_messages, read_info
from sim.sensors.lidar import Lidar, LidarConfig
from sim.sensors.truth import TruthSample
from sim.vehicle_log import scan_record, threats_from_dict

NAN = float("nan")
_STATE = {
    "t": 5.000000000000036,
    "pos_ned": [-1.2526965411540774, -0.01146291248108633, -11.443251569709219],
    "vel_ned": [0.1046313871409471, -0.12029671513618498, -3.0804876122680134],
    "euler": [0.0006571813423593382, 0.01564814866981623, -0.024742515024961165],
    "rates_body": [-0.04437470459061077, 0.017801752418870213, 6.993683759765904e-05],
    "alt_msl_m": 411.4432515697092,
    "lat_deg": 46.99998873251643,
    "lon_deg": 7.999999849292991,
    "tas_mps": 3.084610665251658,
    "eas_mps": 0.0,
    "alpha_rad": -1.5202395027020168,
    "beta_rad": -0.0,
}
_SENSORS = {
    "t": 4.0,
    "imu": [
        {"t": 3.95, "dt": 0.05, "accel_body": [0.1, -0.2, -9.81], "gyro_body": [1e-3, 2e-3, -3e-3]},
        {"t": 4.0, "dt": 0.05, "accel_body": [0.2, -0.1, -9.8], "gyro_body": [0.0, 0.0, 0.0]},
    ],
    "gnss": [{"t": 3.8, "pos_ned": [15234.567891, -2.0, -18000.25], "vel_ned": [4.0, 5.0, 6.0]}],
    "baro": [{"t": 3.9, "pressure_pa": 7565.2}],
    "mag": [{"t": 3.9, "field_body_ut": [20.0, 1.0, 43.0]}],
}


def _float32(sensors: dict) -> dict:
    """The measured values (not the times) rounded to float32, as cosim.Sensors stores them."""

    def rnd(v):
        return [float(np.float32(x)) for x in v] if isinstance(v, list) else float(np.float32(v))

    return {
        k: v if k == "t" else [{f: x if f in ("t", "dt") else rnd(x) for f, x in r.items()} for r in v]
        for k, v in sensors.items()
    }


# (JSON Schema, message as written, as it reads back)
CASES = [
    (S.VEHICLE_STATE, _STATE, _STATE),
    (S.TRACKING, {"t": 1.5, "cross_track_m": -0.25, "leg": -1}, None),
    (
        S.FIXED_WING_SETPOINT,
        {
            "t": 0.1,
            "roll_rad": 0.3,
            "altitude_m": 18000.0,
            "tas_mps": 26.0,
            "leg": 3,
            "cross_track_m": 1e-9,
            "turning": True,
        },
        None,
    ),
    (
        S.MULTIROTOR_SETPOINT,
        {
            "t": 2.0,
            "pos_ned": [NAN, 1.0, -20.0],
            "vel_ned": [0.0, 0.0, 1.5],
            "yaw_rad": NAN,
            "altitude_m": math.inf,
            "leg": 0,
            "cross_track_m": 0.5,
            "turning": False,
        },
        {
            "t": 2.0,
            "pos_ned": [None, 1.0, -20.0],
            "vel_ned": [0.0, 0.0, 1.5],
            "yaw_rad": None,
            "altitude_m": None,
            "leg": 0,
            "cross_track_m": 0.5,
            "turning": False,
        },
    ),
    (
        S.COMMANDS,
        {"t": 3.0, "properties": {"fcs/throttle-cmd-norm": 0.7, "ap/armed": 1.0}, "debug": {"x": NAN}},
        {"t": 3.0, "properties": {"fcs/throttle-cmd-norm": 0.7, "ap/armed": 1.0}, "debug": {"x": None}},
    ),
    (S.SENSORS, _SENSORS, _float32(_SENSORS)),
    (
        S.ESTIMATE_SIGMA,
        {
            "t": 4.0,
            "pos": [1.5, 1.5, 4.2],
            "vel": [0.06, 0.09, 0.12],
            "att": [0.04, 0.002, 0.06],
            "heading": [0.06],
            "accel": [0.04, 0.35, 0.05],
            "gyro": [0.004, 0.0008, 0.006],
            "baro": [4.18],
            "bias": {"accel": [-0.07, 0.11, -0.14], "gyro": [-0.001, 0.01, 0.0008], "baro": [-0.18], "gnss_gm": []},
        },
        None,
    ),
    (
        S.ENERGY,
        {
            "t": 60.0,
            "state_of_charge": 0.5,
            "energy_wh": 3825.0,
            "solar_w": 1200.5,
            "propulsion_w": 600.25,
            "loads_w": 40.0,
            "total_w": 560.25,
            "battery_w": 540.0,
            "loss_w": 20.25,
            "curtailed_w": 0.0,
            "shortfall_w": 0.0,
            "sun_elevation_deg": 45.0,
            "incidence_cos": 0.7,
            "depleted": False,
            "cumulative_wh": {
                "solar": 20.0,
                "propulsion": 10.0,
                "loads": 0.5,
                "loss": 0.1,
                "curtailed": 0.0,
                "shortfall": 0.0,
            },
        },
        None,
    ),
]


def _write_read(tmp_path, compact: bool) -> list[dict]:
    path = tmp_path / f"{compact}.mcap"
    with McapLog(path, 10**18, background=False, compact=compact) as log:
        for k, (schema, msg, _) in enumerate(CASES):
            log.write_record(f"/v/{k}", float(k), msg, schema)
    return [m for _, _, m in sorted(iter_messages(path), key=lambda x: x[0])]


def _same(a, b) -> bool:
    """Equal, floats bit for bit (0.0 and -0.0 apart)."""
    if isinstance(a, float) and isinstance(b, float):
        return math.copysign(1.0, a) == math.copysign(1.0, b) and a == b
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    return type(a) is type(b) and a == b


def test_protobuf_topics_read_back_the_values_written(tmp_path):
    got = _write_read(tmp_path, compact=True)
    for (schema, written, expected), back in zip(CASES, got, strict=True):
        assert _same(back, expected or written), schema["title"]


def test_protobuf_and_json_logs_read_back_the_same_dicts(tmp_path):
    proto, js = _write_read(tmp_path, compact=True), _write_read(tmp_path, compact=False)
    for (schema, _, _), a, b in zip(CASES, proto, js, strict=True):
        assert a == (_float32(b) if schema is S.SENSORS else b), schema["title"]
    with McapLog(tmp_path / "c.mcap", 0, background=False) as log:
        log.write_record("/v/state", 0.0, _STATE, S.VEHICLE_STATE)
        log.write_record(
            "/v/mission", 0.0, {"t": 0.0, "next_waypoint": 1, "waypoints": 2, "complete": False}, S.MISSION_STATUS
        )
    enc = {t.topic: (t.encoding, t.schema) for t in read_info(tmp_path / "c.mcap").topics}
    assert enc == {"/v/state": ("protobuf", "cosim.VehicleState"), "/v/mission": ("json", "cosim.MissionStatus")}


def test_a_key_the_message_lacks_is_a_clear_error():
    with pytest.raises(ValueError, match=r"cosim\.Tracking"):
        log_proto.encode("cosim.Tracking", {"t": 1.0, "cross_track": 2.0})


@pytest.mark.parametrize("background", [False, True])
def test_a_key_the_message_lacks_fails_the_log_with_its_name(tmp_path, background):
    log = McapLog(tmp_path / "bad.mcap", 0, background=background)
    log.write_record("/v/tracking", 0.0, {"t": 0.0, "cross_track": 1.0}, S.TRACKING)
    with pytest.raises(LogWriteError, match=r"cosim\.Tracking.*cross_track"):
        log.close()


def test_every_message_mirrors_its_json_schema():
    titles = {v["title"]: v for v in vars(S).values() if isinstance(v, dict) and "title" in v}
    for name, fields in log_proto.MESSAGES.items():
        if name.endswith(("Record", "Bias")):  # nested in Sensors / EstimateSigma
            continue
        props = titles[f"cosim.{name}"]["properties"]
        assert [f for f, _, _ in fields] == list(props), name


def _scan(resolution: float = 0.001):
    cfg = LidarConfig(max_range_m=30.0, range_resolution_m=resolution, azimuth_step_deg=2.0, elevation_step_deg=3.0)
    ob = PrismObstacle("b", box(8.0, -20.0, 12.0, 20.0), 0.0, 100.0)
    lidar = Lidar(cfg, [ob], np.random.default_rng(4))
    truth = VehicleState(
        0.0, np.array([0.0, 0.0, -10.0]), np.zeros(3), np.array([0.05, -0.02, 0.3]), np.zeros(3), 0.0, 0.0, 0.0
    )
    est = VehicleState(
        0.0, np.array([0.1, -0.2, -10.3]), np.zeros(3), np.array([0.01, 0.0, 0.2987]), np.zeros(3), 0.0, 0.0, 0.0
    )
    ret = lidar.poll(TruthSample(truth, np.array([0.0, 0.0, -9.8]), 95e3, 288.0, 1.2, np.zeros(3)))[0]
    return ret.to_scan(est)


def test_lidar_scan_reads_back_bit_identical(tmp_path):
    scan = _scan()
    assert 0 < scan.hit.sum() < len(scan.hit)
    path = tmp_path / "scan.mcap"
    with McapLog(path, 0, background=False) as log:
        log.write_record("/v/threats/lidar", 1.0, scan_record(scan), S.LIDAR_SCAN)
    ((_, _, d),) = list(iter_messages(path))
    back = threats_from_dict({"intruders": [], "spheres": [], "storms": [], "lidar": d}, [], []).lidar
    assert back is not None
    for f in ("origin_ned", "directions_ned", "ranges_m", "hit", "rotation"):
        assert np.array_equal(getattr(back, f), getattr(scan, f)), f
    assert (back.t, back.max_range_m, back.pattern, back.range_resolution_m) == (
        scan.t,
        scan.max_range_m,
        scan.pattern,
        scan.range_resolution_m,
    )
    assert len(log_proto.encode("cosim.LidarScan", scan_record(scan))) < 3 * len(scan.hit) / 8 + 4 * scan.hit.sum()


def test_lidar_ranges_are_whole_resolution_steps():
    for res in (0.001, 0.25):
        scan = _scan(res)
        r = scan.ranges_m[scan.hit]
        assert np.array_equal(r, np.rint(r / res) * res)  # a whole number of steps, as computed on reading
    assert not np.array_equal(_scan(0.001).ranges_m, _scan(0.25).ranges_m)


def test_a_scan_without_its_pattern_is_not_logged():
    scan = _scan()
    bare = type(scan)(scan.t, scan.origin_ned, scan.directions_ned, scan.ranges_m, scan.hit, scan.max_range_m)
    with pytest.raises(ValueError, match="pattern"):
        scan_record(bare)
