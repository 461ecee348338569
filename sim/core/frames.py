"""Frames and attitude algebra, in one place (numpy and ``math`` only).

- The scenario's *local-level NED* frame [m] (north/east on the tangent plane at the origin, down
  = origin altitude - altitude); its geodetic (WGS84) mapping lives in the engine (``sim.geodesy``).
- The seed algorithms are z-up (ENU); :func:`ned_to_enu` / :func:`enu_to_ned` are the one boundary.
- Quaternions are Hamilton, scalar first ``(w, x, y, z)``, rotating body FRD -> NED:
  ``v_ned = R(q) v_body`` (consumers that want another order, e.g. Foxglove's named x, y, z, w
  fields, unpack by name). Euler angles are 3-2-1 (yaw, pitch, roll) [rad].
"""

from __future__ import annotations

import math

import numpy as np


def ned_to_enu(v) -> np.ndarray:
    """NED vector(s) to ENU (z-up), last axis."""
    v = np.asarray(v, float)
    return np.stack([v[..., 1], v[..., 0], -v[..., 2]], axis=-1)


def enu_to_ned(v) -> np.ndarray:
    """ENU vector(s) to NED, last axis (the map is its own inverse)."""
    return ned_to_enu(v)


def wrap_pi(a):
    """Angle(s) wrapped to (-pi, pi] [rad]."""
    return np.pi - np.mod(np.pi - np.asarray(a, float), 2.0 * np.pi)


def euler_to_dcm(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Rotation matrix body FRD -> NED of 3-2-1 Euler angles [rad]."""
    cr, sr, cp, sp, cy, sy = (
        math.cos(roll),
        math.sin(roll),
        math.cos(pitch),
        math.sin(pitch),
        math.cos(yaw),
        math.sin(yaw),
    )
    return np.array(
        [
            [cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy],
            [cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy],
            [-sp, sr * cp, cr * cp],
        ]
    )


def dcm_to_euler(r: np.ndarray) -> np.ndarray:
    """3-2-1 Euler angles (roll, pitch, yaw) [rad] of a body -> NED rotation matrix."""
    return np.array(
        [math.atan2(r[2, 1], r[2, 2]), -math.asin(max(-1.0, min(1.0, r[2, 0]))), math.atan2(r[1, 0], r[0, 0])]
    )


def euler_to_quat(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    """Quaternion (w, x, y, z) of 3-2-1 Euler angles [rad], body FRD -> NED."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )


def quat_to_dcm_rows(q: tuple[float, float, float, float]) -> tuple[float, ...]:
    """Rotation matrix body FRD -> NED of a unit quaternion, row-major as 9 plain floats."""
    w, x, y, z = q
    return (
        1 - 2 * (y * y + z * z),
        2 * (x * y - w * z),
        2 * (x * z + w * y),
        2 * (x * y + w * z),
        1 - 2 * (x * x + z * z),
        2 * (y * z - w * x),
        2 * (x * z - w * y),
        2 * (y * z + w * x),
        1 - 2 * (x * x + y * y),
    )


def quat_to_dcm(q: tuple[float, float, float, float]) -> np.ndarray:
    """Rotation matrix body FRD -> NED (3x3) of a unit quaternion."""
    return np.array(quat_to_dcm_rows(q)).reshape(3, 3)


def quat_to_euler(q: tuple[float, float, float, float]) -> tuple[float, float, float]:
    """3-2-1 Euler angles (roll, pitch, yaw) [rad] of a unit quaternion, body FRD -> NED, as
    plain floats (the same bits as :func:`dcm_to_euler` of :func:`quat_to_dcm`)."""
    w, x, y, z = q
    s = 2.0 * (w * y - x * z)
    return (
        math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y)),
        math.asin(-1.0 if s < -1.0 else min(s, 1.0)),
        math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)),
    )


def yaw_error_variance(q: tuple[float, float, float, float], p_att: list[float]) -> float:
    """Variance [rad^2] of the NED-frame yaw error of attitude ``q`` (w, x, y, z; body FRD ->
    NED) with body-frame attitude-error covariance ``p_att`` (3 x 3 row-major, 9 floats [rad^2]):
    ``(C P C^T)[2, 2]``, C the body -> NED DCM. Plain float arithmetic in a fixed order, so the
    same inputs give the same bits in any process."""
    w, x, y, z = q
    c = (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y))
    return sum(c[i] * p_att[3 * i + j] * c[j] for i in range(3) for j in range(3))


def quat_mul(a, b) -> tuple[float, float, float, float]:
    """Hamilton product ``a (x) b``."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


def quat_exp(rx: float, ry: float, rz: float) -> tuple[float, float, float, float]:
    """Unit quaternion of the rotation vector (rx, ry, rz) [rad]."""
    a = math.sqrt(rx * rx + ry * ry + rz * rz)
    if a < 1e-9:
        return (1.0, 0.5 * rx, 0.5 * ry, 0.5 * rz)
    s = math.sin(0.5 * a) / a
    return (math.cos(0.5 * a), s * rx, s * ry, s * rz)


def quat_normalize(q) -> tuple[float, float, float, float]:
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


def quat_log(q) -> np.ndarray:
    """Rotation vector [rad] of a unit quaternion (shortest rotation)."""
    w, x, y, z = q if q[0] >= 0.0 else (-q[0], -q[1], -q[2], -q[3])
    s = math.sqrt(x * x + y * y + z * z)
    if s < 1e-12:
        return np.array([2.0 * x, 2.0 * y, 2.0 * z])
    k = 2.0 * math.atan2(s, w) / s
    return np.array([k * x, k * y, k * z])


def quat_conj(q) -> tuple[float, float, float, float]:
    return (q[0], -q[1], -q[2], -q[3])
