"""The attitude and body rates an autopilot's inner loops close on, at every gyro sample.

A real autopilot runs its rate loop on each gyro sample and its attitude loop on the attitude
estimate propagated with that gyro between filter updates. Here: after every EKF fusion the
attitude restarts from the filter's posterior quaternion; each later gyro sample ``w`` (body FRD
[rad/s]) is corrected by the filter's gyro bias estimate ``bg`` and turns the attitude by
``(w - bg) dt``, ``dt`` [s] the time since the previous sample (rectangular rule: the error over a
fusion interval T is about |d(w)/dt| T^2 / 2, 4e-4 rad for a 0.1 s HAPS interval at 0.1 rad/s^2).
The rates handed on are the bias-corrected gyro sample itself (noise included).

Frames: quaternion (w, x, y, z), Hamilton, body FRD -> NED; Euler angles 3-2-1 [rad].
Plain float math: this runs at the IMU rate.
"""

from __future__ import annotations

from sim.core.frames import quat_exp, quat_mul, quat_to_euler
from sim.core.state import AttitudeSample

Quat = tuple[float, float, float, float]


class GyroAttitude:
    """Attitude propagated with the bias-corrected gyro from the last fusion (see module doc)."""

    def __init__(self, q: Quat, gyro_bias: tuple[float, float, float]):
        self._q = q
        self._bg = gyro_bias
        self.sample: AttitudeSample | None = None  # the newest inner-loop inputs

    def restart(self, t: float, q: Quat, gyro_bias: tuple[float, float, float], gyro: tuple[float, float, float]):
        """A fusion at ``t`` [s]: the posterior attitude ``q`` and gyro bias [rad/s], with the
        gyro sample ``gyro`` [rad/s] of the same instant."""
        self._q = q
        self._bg = gyro_bias
        bx, by, bz = gyro_bias
        self.sample = AttitudeSample(t, quat_to_euler(q), (gyro[0] - bx, gyro[1] - by, gyro[2] - bz))

    def step(self, t: float, gyro: tuple[float, float, float], dt: float) -> None:
        """The gyro sample ``gyro`` [rad/s] taken at ``t`` [s], ``dt`` [s] after the previous one."""
        bx, by, bz = self._bg
        p, q, r = gyro[0] - bx, gyro[1] - by, gyro[2] - bz
        self._q = quat_mul(self._q, quat_exp(p * dt, q * dt, r * dt))
        self.sample = AttitudeSample(t, quat_to_euler(self._q), (p, q, r))
