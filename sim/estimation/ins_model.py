"""Error-state INS model: nominal state, IMU propagation, measurement models, and their
Jacobians — analytic, and by finite differences (the verification and benchmark baseline).

Nominal state (local NED, flat non-rotating earth, constant gravity):
  p [m], v [m/s] NED; q body FRD -> NED (Hamilton, scalar first); accelerometer bias ba
  [m/s^2] and gyro bias bg [rad/s] body; baro altitude bias bb [m]; GNSS position error
  (Gauss-Markov) gm NED [m].
Error state (19): dp, dv, dtheta (body-frame attitude error, q_true = q (x) Exp(dtheta)), dba,
dbg, dbb, dgm — indices in ``IDX``.

IMU mechanisation over dt with the averaged samples (f, w) of its two ends:
  w_hat = w - bg, f_hat = f - ba, R = R(q (x) Exp(w_hat dt / 2))   (mid-interval attitude)
  a = R f_hat + g;  p += C (v dt + a dt^2 / 2);  v += a dt;  q = q (x) Exp(w_hat dt);
  gm *= exp(-dt / tau).

Frames: v, q, f, w, gravity are in the local NED frame at the vehicle (where JSBSim, the GNSS
velocity and the magnetometer express them); p and gm are scenario coordinates (tangent plane
at the origin, local-level D), where the GNSS position is. ``C`` (3x3,
:meth:`sim.estimation.geodetic.LocalGeodetic.velocity_map`, held constant over a step) maps a
local velocity to the rate of the scenario coordinates; the identity at the origin. Without it
a flat-earth filter integrates the local velocity into the scenario position and drifts by the
meridian convergence (0.19 deg at 20 km east at 47 deg N: 0.09 m/s at 26 m/s), which GNSS
position fixes then push into the Gauss-Markov state far beyond its prior.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sim.core.constants import STANDARD_GRAVITY
from sim.core.frames import (
    quat_conj,
    quat_exp,
    quat_log,
    quat_mul,
    quat_normalize,
    quat_to_dcm_rows,
    yaw_error_variance,
)

N = 19
IDX = {
    "p": slice(0, 3),
    "v": slice(3, 6),
    "th": slice(6, 9),
    "ba": slice(9, 12),
    "bg": slice(12, 15),
    "bb": slice(15, 16),
    "gm": slice(16, 19),
}
GRAVITY = np.array([0.0, 0.0, STANDARD_GRAVITY])
_I3 = np.eye(3)


def three_sd(variance: float) -> float:
    """3 standard deviations [the variance's unit's root]; NaN for a negative variance (as numpy)."""
    return three_sds((variance,))[0]


def three_sds(variances: Sequence[float]) -> list[float]:
    """:func:`three_sd` of each variance (one call for many: the log computes some per tick)."""
    sqrt, nan = math.sqrt, math.nan
    return [3.0 * sqrt(v) if v >= 0.0 else nan for v in variances]


def sigma_bounds(var: Sequence[float], q: Sequence[float], p_att: Sequence[float]) -> dict[str, list[float]]:
    """3-sigma bounds of the error state from the covariance diagonal ``var`` (its first 16, in
    :data:`IDX` order), attitude ``q`` (w, x, y, z) and the attitude-error covariance block
    ``p_att`` (9, row-major): ``pos`` NED [m], ``vel`` NED [m/s], ``att`` body-frame attitude
    error [rad], ``heading`` [rad] (NED-frame yaw error), biases ``accel`` [m/s^2], ``gyro``
    [rad/s], ``baro`` [m]. Plain float arithmetic: the same bits in the simulation (the EKF's
    bounds) and in the log's writer process (a compact log's ``/<v>/est/sigma3``)."""
    sd = three_sds(var)
    heading = three_sd(yaw_error_variance((q[0], q[1], q[2], q[3]), list(p_att)))
    return {
        "pos": sd[0:3],
        "vel": sd[3:6],
        "att": sd[6:9],
        "heading": [heading],
        "accel": sd[9:12],
        "gyro": sd[12:15],
        "baro": sd[15:16],
    }


@dataclass(slots=True)
class NavState:
    p: np.ndarray
    v: np.ndarray
    q: tuple[float, float, float, float]
    ba: np.ndarray
    bg: np.ndarray
    bb: float
    gm: np.ndarray

    def copy(self) -> NavState:
        return NavState(self.p.copy(), self.v.copy(), self.q, self.ba.copy(), self.bg.copy(), self.bb, self.gm.copy())


def boxplus(s: NavState, dx: np.ndarray) -> NavState:
    """``s`` corrected by the error state ``dx`` (19,)."""
    return NavState(
        s.p + dx[0:3],
        s.v + dx[3:6],
        quat_normalize(quat_mul(s.q, quat_exp(*dx[6:9]))),
        s.ba + dx[9:12],
        s.bg + dx[12:15],
        s.bb + float(dx[15]),
        s.gm + dx[16:19],
    )


def boxminus(a: NavState, b: NavState) -> np.ndarray:
    """Error state ``dx`` with ``a = b [+] dx``."""
    return np.concatenate(
        (
            a.p - b.p,
            a.v - b.v,
            quat_log(quat_mul(quat_conj(b.q), a.q)),
            a.ba - b.ba,
            a.bg - b.bg,
            [a.bb - b.bb],
            a.gm - b.gm,
        )
    )


def skew(v) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


Vec3 = list[float]  # x, y, z as plain floats
Mat3 = tuple[float, ...]  # a 3x3 matrix row-major, 9 plain floats
Vector3 = np.ndarray | Sequence[float]  # a 3-vector as the callers hold it
_I9: Mat3 = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)


def floats3(v: Vector3) -> Vec3:
    """The three components of a 3-vector (array or sequence) as plain floats."""
    return v.tolist() if type(v) is np.ndarray else [float(v[0]), float(v[1]), float(v[2])]


def mat3(c: np.ndarray | Mat3 | None) -> Mat3:
    """A 3x3 matrix (``None``: the identity) as :data:`Mat3`."""
    if c is None:
        return _I9
    return c if isinstance(c, tuple) else tuple(np.asarray(c, float).ravel().tolist())


def rotate(r: Mat3, v: Vec3) -> Vec3:
    """``r v`` for a row-major 3x3 ``r`` and a 3-vector ``v``, plain floats."""
    x, y, z = v
    return [r[0] * x + r[1] * y + r[2] * z, r[3] * x + r[4] * y + r[5] * z, r[6] * x + r[7] * y + r[8] * z]


def propagate(
    s: NavState,
    f: Vector3,
    w: Vector3,
    dt: float,
    gm_decay: float,
    gravity: Vector3 = GRAVITY,
    c_pos: np.ndarray | Mat3 | None = None,
) -> tuple[NavState, Mat3, Vec3, Vec3]:
    """Nominal state after ``dt`` [s]; also the mid-interval R (:data:`Mat3`) and the
    bias-corrected f [m/s^2], w [rad/s] (for Phi). ``f``, ``w``: body FRD 3-vectors. ``gravity``:
    NED gravity vector [m/s^2] (default: standard gravity, down). ``c_pos``: the local-velocity
    -> scenario-position-rate map ``C`` (module doc; 3x3 array or :data:`Mat3`; ``None`` =
    identity). Plain float arithmetic on the 3-vectors (it runs at the fusion rate)."""
    bax, bay, baz = s.ba.tolist()
    bgx, bgy, bgz = s.bg.tolist()
    f0, f1, f2 = floats3(f)
    w0, w1, w2 = floats3(w)
    fh = [f0 - bax, f1 - bay, f2 - baz]
    wh = [w0 - bgx, w1 - bgy, w2 - bgz]
    wx, wy, wz = wh[0] * dt, wh[1] * dt, wh[2] * dt
    r = quat_to_dcm_rows(quat_mul(s.q, quat_exp(0.5 * wx, 0.5 * wy, 0.5 * wz)))
    gx, gy, gz = floats3(gravity)
    ax, ay, az = rotate(r, fh)
    dvx, dvy, dvz = (ax + gx) * dt, (ay + gy) * dt, (az + gz) * dt
    vx, vy, vz = s.v.tolist()
    dp = [(vx + 0.5 * dvx) * dt, (vy + 0.5 * dvy) * dt, (vz + 0.5 * dvz) * dt]
    if c_pos is not None:
        dp = rotate(mat3(c_pos), dp)
    px, py, pz = s.p.tolist()
    nxt = NavState(
        np.array([px + dp[0], py + dp[1], pz + dp[2]]),
        np.array([vx + dvx, vy + dvy, vz + dvz]),
        quat_normalize(quat_mul(s.q, quat_exp(wx, wy, wz))),
        s.ba,
        s.bg,
        s.bb,
        s.gm * gm_decay,
    )
    return nxt, r, fh, wh


# flat indices into the N x N transition of the entries that change with the step (row-major
# within each block): dp/dv, dp/d(theta, ba), dv/d(theta, ba), dv/dbg, dtheta/dtheta
_PHI_IDX = np.array(
    [r * N + c for r in range(0, 3) for c in range(3, 6)]
    + [r * N + c for r in range(0, 3) for c in range(6, 12)]
    + [r * N + c for r in range(3, 6) for c in range(6, 12)]
    + [r * N + c for r in range(3, 6) for c in range(12, 15)]
    + [r * N + c for r in range(6, 9) for c in range(6, 9)]
)
_CONST_IDX = (np.array([6, 7, 8, 16, 17, 18]), np.array([12, 13, 14, 16, 17, 18]))


def transition_analytic(
    out: np.ndarray,
    r: Mat3,
    fh: Vec3,
    wh: Vec3,
    dt: float,
    gm_decay: float,
    c_pos: np.ndarray | Mat3 | None = None,
) -> np.ndarray:
    """Error-state transition Phi (19x19) written into ``out`` (an identity the caller reuses:
    only the entries below change); first order in dt except the attitude block and the
    dt^2 terms of dp and dv. ``r``, ``fh``, ``wh``: from :func:`propagate`. ``c_pos``: as in
    :func:`propagate` (the dp rows are ``C`` times the flat-earth ones). The 63 changing
    entries are worked out in plain floats and written in one ``put``."""
    fx, fy, fz = fh
    # rfr = [R [f]x, R] (3x6), row-major
    rfr: list[float] = []
    for i in range(0, 9, 3):
        r0, r1, r2 = r[i], r[i + 1], r[i + 2]
        rfr += (r1 * fz - r2 * fy, r2 * fx - r0 * fz, r0 * fy - r1 * fx, r0, r1, r2)
    c = mat3(c_pos)
    k = 0.5 * dt * dt
    vals = [x * dt for x in c]
    a0, a1, a2, a3, a4, a5, b0, b1, b2, b3, b4, b5, d0, d1, d2, d3, d4, d5 = rfr
    for i in range(0, 9, 3):  # -k C rfr, row by row
        ca, cb, cd = c[i], c[i + 1], c[i + 2]
        vals += (
            -k * (ca * a0 + cb * b0 + cd * d0),
            -k * (ca * a1 + cb * b1 + cd * d1),
            -k * (ca * a2 + cb * b2 + cd * d2),
            -k * (ca * a3 + cb * b3 + cd * d3),
            -k * (ca * a4 + cb * b4 + cd * d4),
            -k * (ca * a5 + cb * b5 + cd * d5),
        )
    vals += [x * -dt for x in rfr]
    vals += [rfr[j] * k for j in (0, 1, 2, 6, 7, 8, 12, 13, 14)]
    a = quat_to_dcm_rows(quat_exp(wh[0] * dt, wh[1] * dt, wh[2] * dt))
    vals += (a[0], a[3], a[6], a[1], a[4], a[7], a[2], a[5], a[8])  # its transpose
    out.put(_PHI_IDX, vals)
    if out[6, 12] != -dt or out[16, 16] != gm_decay:  # constant for a fixed step: set once
        out[_CONST_IDX] = (-dt, -dt, -dt, gm_decay, gm_decay, gm_decay)
    return out


def transition_numeric(
    s: NavState,
    f: np.ndarray,
    w: np.ndarray,
    dt: float,
    gm_decay: float,
    eps: float = 1e-6,
    c_pos: np.ndarray | None = None,
) -> np.ndarray:
    """Phi by forward differences of :func:`propagate` over each error-state axis (``C`` held
    fixed, as the filter does over a step)."""
    base = propagate(s, f, w, dt, gm_decay, c_pos=c_pos)[0]
    phi = np.empty((N, N))
    dx = np.zeros(N)
    for j in range(N):
        dx[j] = eps
        phi[:, j] = boxminus(propagate(boxplus(s, dx), f, w, dt, gm_decay, c_pos=c_pos)[0], base) / eps
        dx[j] = 0.0
    return phi


# -- measurement models: h(s, ...) and analytic H ------------------------------------------------


def gnss_prediction(s: NavState, lag: float, acc_ned: Vec3, c: Mat3) -> list[float]:
    """:func:`h_gnss` as 6 plain floats (``acc_ned`` [m/s^2] and ``C`` as floats)."""
    px, py, pz = s.p.tolist()
    gx, gy, gz = s.gm.tolist()
    v = s.v.tolist()
    cx, cy, cz = rotate(c, v)
    ax, ay, az = acc_ned
    return [
        px + gx - cx * lag,
        py + gy - cy * lag,
        pz + gz - cz * lag,
        v[0] - ax * lag,
        v[1] - ay * lag,
        v[2] - az * lag,
    ]


def h_gnss(s: NavState, lag: float, acc_ned: Vector3, c_pos: np.ndarray | Mat3 | None = None) -> np.ndarray:
    """GNSS position [m] and velocity [m/s] ``lag`` [s] before the filter time (first-order
    back-shift with the NED acceleration ``acc_ned`` [m/s^2]; the position one moves along
    ``C v``, the scenario-frame rate)."""
    return np.array(gnss_prediction(s, lag, floats3(acc_ned), mat3(c_pos)))


def H_gnss(out: np.ndarray, lag: float, c_pos: np.ndarray | None = None) -> np.ndarray:
    """6x19; the caller keeps the constant identities; sets the lag terms."""
    out[0:3, 3:6] = (_I3 if c_pos is None else c_pos) * -lag
    return out


def h_baro(s: NavState) -> np.ndarray:
    """Baro height above the origin [m] = -D + bias."""
    return np.array([-s.p[2] + s.bb])


def mag_prediction(q: tuple[float, float, float, float], field_ned: Vec3) -> Vec3:
    """:func:`h_mag` as plain floats: ``R(q)^T m_ned``."""
    r = quat_to_dcm_rows(q)
    mx, my, mz = field_ned
    return [r[0] * mx + r[3] * my + r[6] * mz, r[1] * mx + r[4] * my + r[7] * mz, r[2] * mx + r[5] * my + r[8] * mz]


def h_mag(s: NavState, field_ned: Vector3) -> np.ndarray:
    """Magnetometer field in body FRD [uT]: ``R^T m_ned`` (known earth field ``m_ned`` [uT])."""
    return np.array(mag_prediction(s.q, floats3(field_ned)))


def H_mag(out: np.ndarray, field_body: Vector3) -> np.ndarray:
    """3x19: d (R Exp(dtheta))^T m / d dtheta = [m_body]x."""
    out[0:3, 6:9] = skew(field_body)
    return out


def jacobian_numeric(h, s: NavState, eps: float = 1e-6) -> np.ndarray:
    """d h(s [+] dx) / d dx at dx = 0 by forward differences."""
    base = h(s)
    cols = []
    dx = np.zeros(N)
    for j in range(N):
        dx[j] = eps
        cols.append((h(boxplus(s, dx)) - base) / eps)
        dx[j] = 0.0
    return np.stack(cols, axis=1)
