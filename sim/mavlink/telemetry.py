"""VehicleState -> MAVLink telemetry messages (pure functions, no I/O).

Scaling follows the MAVLink common definitions: angles in ATTITUDE are rad and rad/s (body
rates p, q, r), GLOBAL_POSITION_INT has lat/lon [degE7], ``alt`` MSL [mm], ``relative_alt`` above
home [mm] (home = the scenario origin), velocities NED [cm/s], heading [cdeg]; VFR_HUD ``airspeed``
is the equivalent airspeed (closest to the indicated airspeed a GCS expects) [m/s], ``alt`` MSL
[m], ``climb`` up [m/s]. ``time_boot_ms`` is sim time [ms]. Integer fields are clamped to their
wire range so that no value can make packing raise.
"""

from __future__ import annotations

import math
import zlib

import numpy as np
from pymavlink.dialects.v20 import common as mav

from sim.core.state import VehicleState
from sim.core.threats import IntruderTrack
from sim.geodesy import GeoPoint, ned_to_geodetic
from sim.mavlink.modes import Mode, base_mode

MAV_TYPES = {"fixed_wing": mav.MAV_TYPE_FIXED_WING, "multirotor": mav.MAV_TYPE_QUADROTOR}

# what a simulated vehicle "has": IMU, mag, baro, pitot, GNSS, AHRS and the control loops
_SENSORS = (
    mav.MAV_SYS_STATUS_SENSOR_3D_GYRO
    | mav.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | mav.MAV_SYS_STATUS_SENSOR_3D_MAG
    | mav.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    | mav.MAV_SYS_STATUS_SENSOR_DIFFERENTIAL_PRESSURE
    | mav.MAV_SYS_STATUS_SENSOR_GPS
    | mav.MAV_SYS_STATUS_AHRS
    | mav.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
    | mav.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
    | mav.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
    | mav.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
)
_ADSB_FLAGS = (
    mav.ADSB_FLAGS_VALID_COORDS
    | mav.ADSB_FLAGS_VALID_ALTITUDE
    | mav.ADSB_FLAGS_VALID_HEADING
    | mav.ADSB_FLAGS_VALID_VELOCITY
    | mav.ADSB_FLAGS_VALID_CALLSIGN
    | mav.ADSB_FLAGS_VERTICAL_VELOCITY_VALID
    | mav.ADSB_FLAGS_SIMULATED
)


def _clamp(x: float, lo: int, hi: int) -> int:
    return int(min(max(round(x), lo), hi))


def _i16(x: float) -> int:
    return _clamp(x, -32768, 32767)


def _i32(x: float) -> int:
    return _clamp(x, -(2**31), 2**31 - 1)


def _heading_cdeg(rad: float) -> int:
    """Heading [rad, from north, positive east] -> [cdeg] in 0..35999."""
    return round(math.degrees(rad) * 100.0) % 36000


def time_boot_ms(t: float) -> int:
    """Sim time [s] -> ``time_boot_ms`` (uint32 wraps after 49.7 days)."""
    return round(t * 1000.0) % 2**32


def is_finite(state: VehicleState) -> bool:
    """True when every field the telemetry uses is finite (a diverged state is not sent)."""
    scalars = (state.alt_msl_m, state.lat_deg, state.lon_deg, state.tas_mps, state.eas_mps)
    vectors = (state.pos_ned, state.vel_ned, state.euler, state.rates_body)
    return all(math.isfinite(x) for x in scalars) and all(np.all(np.isfinite(v)) for v in vectors)


def heartbeat(m: mav.MAVLink, vehicle_type: str, mode: Mode, armed: bool) -> mav.MAVLink_message:
    return m.heartbeat_encode(
        MAV_TYPES[vehicle_type],
        mav.MAV_AUTOPILOT_GENERIC,
        base_mode(mode, armed),
        mode.custom_mode,
        mav.MAV_STATE_ACTIVE,
    )


def sys_status(m: mav.MAVLink, comm_errors: int) -> mav.MAVLink_message:
    """All sensors present, enabled and healthy; battery unknown; ``comm_errors`` = malformed
    packets received so far."""
    return m.sys_status_encode(
        _SENSORS, _SENSORS, _SENSORS, 0, 65535, -1, -1, 0, _clamp(comm_errors, 0, 65535), 0, 0, 0, 0
    )


def attitude(m: mav.MAVLink, s: VehicleState) -> mav.MAVLink_message:
    p, q, r = (float(x) for x in s.rates_body)
    return m.attitude_encode(time_boot_ms(s.t), s.roll, s.pitch, s.yaw, p, q, r)


def global_position_int(m: mav.MAVLink, s: VehicleState, origin: GeoPoint) -> mav.MAVLink_message:
    vn, ve, vd = (float(x) * 100.0 for x in s.vel_ned)
    return m.global_position_int_encode(
        time_boot_ms(s.t),
        _i32(s.lat_deg * 1e7),
        _i32(s.lon_deg * 1e7),
        _i32(s.alt_msl_m * 1000.0),
        _i32((s.alt_msl_m - origin.alt_m) * 1000.0),
        _i16(vn),
        _i16(ve),
        _i16(vd),
        _heading_cdeg(s.yaw),
    )


def vfr_hud(m: mav.MAVLink, s: VehicleState) -> mav.MAVLink_message:
    """Throttle [%] from ``state.extra['throttle']`` (0..1) when the plant provides it, else 0."""
    throttle = _clamp(100.0 * s.extra.get("throttle", 0.0), 0, 100)
    return m.vfr_hud_encode(
        s.eas_mps, s.ground_speed_mps, _heading_cdeg(s.yaw) // 100, throttle, s.alt_msl_m, -float(s.vel_ned[2])
    )


def mission_current(m: mav.MAVLink, seq: int, total: int) -> mav.MAVLink_message:
    return m.mission_current_encode(_clamp(seq, 0, 65535), _clamp(total, 0, 65535))


def home_position(m: mav.MAVLink, origin: GeoPoint) -> mav.MAVLink_message:
    """HOME_POSITION = the scenario origin, which is also the local NED origin (x = y = z = 0)."""
    return m.home_position_encode(
        _i32(origin.lat_deg * 1e7),
        _i32(origin.lon_deg * 1e7),
        _i32(origin.alt_m * 1000.0),
        0.0,
        0.0,
        0.0,
        [1.0, 0.0, 0.0, 0.0],
        0.0,
        0.0,
        0.0,
    )


def icao_address(track_id: str) -> int:
    """A stable 24-bit ICAO address for a track id (CRC-32 of the id, low 24 bits)."""
    return zlib.crc32(track_id.encode()) & 0xFFFFFF


def adsb_vehicle(m: mav.MAVLink, track: IntruderTrack, origin: GeoPoint, t: float) -> mav.MAVLink_message:
    """An intruder track as ADSB_VEHICLE: geometric altitude MSL [mm], course over ground
    [cdeg], horizontal speed [cm/s], vertical speed up [cm/s], callsign = track id (8 chars),
    ``tslc`` = age of the track at sim time ``t`` [s]."""
    lat, lon, alt = ned_to_geodetic(track.pos_ned, origin)
    vn, ve, vd = (float(x) for x in track.vel_ned)
    emitter = mav.ADSB_EMITTER_TYPE_UAV if track.cooperative else mav.ADSB_EMITTER_TYPE_NO_INFO
    return m.adsb_vehicle_encode(
        icao_address(track.id),
        _i32(float(lat) * 1e7),
        _i32(float(lon) * 1e7),
        mav.ADSB_ALTITUDE_TYPE_GEOMETRIC,
        _i32(float(alt) * 1000.0),
        _heading_cdeg(math.atan2(ve, vn)),
        _clamp(math.hypot(vn, ve) * 100.0, 0, 65535),
        _i16(-vd * 100.0),
        track.id[:8].encode(),
        emitter,
        _clamp(t - track.t, 0, 255),
        _ADSB_FLAGS,
        0,
    )
