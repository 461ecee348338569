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
    quat_to_dcm,
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


def propagate(
    s: NavState,
    f: np.ndarray,
    w: np.ndarray,
    dt: float,
    gm_decay: float,
    gravity: np.ndarray = GRAVITY,
    c_pos: np.ndarray | None = None,
) -> tuple[NavState, np.ndarray, np.ndarray, np.ndarray]:
    """Nominal state after ``dt`` [s]; also the mid-interval R and bias-corrected f, w (for F).
    ``gravity``: NED gravity vector [m/s^2] (default: standard gravity, down). ``c_pos``: the
    local-velocity -> scenario-position-rate map ``C`` (module doc; ``None`` = identity)."""
    fh = f - s.ba
    wh = w - s.bg
    wx, wy, wz = float(wh[0]) * dt, float(wh[1]) * dt, float(wh[2]) * dt
    r = quat_to_dcm(quat_mul(s.q, quat_exp(0.5 * wx, 0.5 * wy, 0.5 * wz)))
    dv = (r @ fh + gravity) * dt
    dp = (s.v + 0.5 * dv) * dt
    nxt = NavState(
        s.p + (dp if c_pos is None else c_pos @ dp),
        s.v + dv,
        quat_normalize(quat_mul(s.q, quat_exp(wx, wy, wz))),
        s.ba,
        s.bg,
        s.bb,
        s.gm * gm_decay,
    )
    return nxt, r, fh, wh


_CONST_IDX = (np.array([6, 7, 8, 16, 17, 18]), np.array([12, 13, 14, 16, 17, 18]))


def transition_analytic(
    out: np.ndarray,
    r: np.ndarray,
    fh: np.ndarray,
    wh: np.ndarray,
    dt: float,
    gm_decay: float,
    c_pos: np.ndarray | None = None,
) -> np.ndarray:
    """Error-state transition Phi (19x19) written into ``out`` (an identity the caller reuses:
    only the entries below change); first order in dt except the attitude block and the
    dt^2 terms of dp and dv. ``c_pos``: as in :func:`propagate` (the dp rows are ``C`` times
    the flat-earth ones)."""
    rfr = np.concatenate((r @ skew(fh), r), axis=1)  # [R [f]x, R]
    k = 0.5 * dt * dt
    if c_pos is None:
        out[0:3, 3:6] = _I3 * dt
        out[0:3, 6:12] = rfr * -k
    else:
        out[0:3, 3:6] = c_pos * dt
        out[0:3, 6:12] = (c_pos @ rfr) * -k
    out[3:6, 6:12] = rfr * -dt
    out[3:6, 12:15] = rfr[:, 0:3] * k
    out[6:9, 6:9] = quat_to_dcm(quat_exp(float(wh[0]) * dt, float(wh[1]) * dt, float(wh[2]) * dt)).T
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


def h_gnss(s: NavState, lag: float, acc_ned: np.ndarray, c_pos: np.ndarray | None = None) -> np.ndarray:
    """GNSS position and velocity ``lag`` [s] before the filter time (first-order back-shift;
    the position one moves along ``C v``, the scenario-frame rate)."""
    vp = s.v if c_pos is None else c_pos @ s.v
    return np.concatenate((s.p + s.gm - vp * lag, s.v - acc_ned * lag))


def H_gnss(out: np.ndarray, lag: float, c_pos: np.ndarray | None = None) -> np.ndarray:
    """6x19; the caller keeps the constant identities; sets the lag terms."""
    out[0:3, 3:6] = (_I3 if c_pos is None else c_pos) * -lag
    return out


def h_baro(s: NavState) -> np.ndarray:
    """Baro height above the origin [m] = -D + bias."""
    return np.array([-s.p[2] + s.bb])


def h_mag(s: NavState, field_ned: np.ndarray) -> np.ndarray:
    """Magnetometer field in body FRD [uT]: ``R^T m_ned`` (known earth field)."""
    return field_ned @ quat_to_dcm(s.q)


def H_mag(out: np.ndarray, field_body: np.ndarray) -> np.ndarray:
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
