"""Constant-velocity Kalman tracks of other aircraft from ADS-B / cooperative reports
(filterpy ``KalmanFilter``, one per intruder id).

State ``[n, e, d, vn, ve, vd]`` local NED [m, m/s]; process noise = piecewise-constant white
acceleration of std ``accel_std`` [m/s^2] per axis (filterpy ``Q_discrete_white_noise``);
measurement = reported position and velocity with the report's noise. A track is created on the
first report, predicted to each report's time of validity and updated; :meth:`tracks` predicts
every live track to the query time without changing it. Tracks silent for ``max_age_s`` are
dropped ([R] ADS-B track lifetime 20 s).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from filterpy.common import Q_discrete_white_noise
from filterpy.kalman import KalmanFilter
from pydantic import Field

from sim.core.threats import IntruderTrack
from sim.sensors.config import StrictConfig
from sim.sensors.measurements import AdsbReport


class TrackerConfig(StrictConfig):
    """Report noise (std) [m, m/s], manoeuvre acceleration std [m/s^2], track lifetime [s],
    body radius [m]."""

    pos_std_ne: float = Field(3.0, gt=0.0)
    pos_std_d: float = Field(5.0, gt=0.0)
    vel_std: float = Field(0.5, gt=0.0)
    accel_std: float = Field(0.5, gt=0.0)
    max_age_s: float = Field(20.0, gt=0.0)
    radius_m: float = Field(1.0, gt=0.0)


def _transition(dt: float) -> np.ndarray:
    f = np.eye(6)
    f[0:3, 3:6] = np.eye(3) * dt
    return f


class IntruderTracker:
    def __init__(self, cfg: TrackerConfig | None = None):
        self.cfg = cfg or TrackerConfig()
        c = self.cfg
        self._R = np.diag([c.pos_std_ne, c.pos_std_ne, c.pos_std_d, c.vel_std, c.vel_std, c.vel_std]) ** 2
        self._filters: dict[str, KalmanFilter] = {}
        self._t: dict[str, float] = {}
        self._coop: dict[str, bool] = {}

    def _q(self, dt: float) -> np.ndarray:
        return Q_discrete_white_noise(dim=2, dt=dt, var=self.cfg.accel_std**2, block_size=3, order_by_dim=False)

    def push(self, reports: Iterable[AdsbReport]) -> None:
        """Fuse reports (each intruder's in time order; older than its track are ignored)."""
        for r in reports:
            kf = self._filters.get(r.id)
            z = np.concatenate((r.pos_ned, r.vel_ned))
            if kf is None:
                kf = self._filters[r.id] = KalmanFilter(dim_x=6, dim_z=6)
                kf.x = z.copy()
                kf.P = self._R.copy()
                kf.H = np.eye(6)
                kf.R = self._R
                self._t[r.id] = r.t
                self._coop[r.id] = r.cooperative
                continue
            dt = r.t - self._t[r.id]
            if dt < 0.0:
                continue
            if dt > 0.0:
                kf.predict(F=_transition(dt), Q=self._q(dt))
            kf.update(z)
            self._t[r.id] = r.t

    def tracks(self, t: float) -> list[IntruderTrack]:
        """Live tracks predicted to ``t`` [s], sorted by id; drops tracks older than ``max_age_s``."""
        out = []
        for iid in sorted(self._filters):
            dt = t - self._t[iid]
            if dt > self.cfg.max_age_s:
                del self._filters[iid], self._t[iid], self._coop[iid]
                continue
            kf = self._filters[iid]
            f = _transition(dt)
            x = f @ kf.x
            p = f @ kf.P @ f.T + (self._q(dt) if dt > 0 else 0.0)
            out.append(
                IntruderTrack(
                    id=iid,
                    t=t,
                    pos_ned=x[:3].copy(),
                    vel_ned=x[3:].copy(),
                    radius_m=self.cfg.radius_m,
                    pos_cov=p[:3, :3].copy(),
                    vel_cov=p[3:, 3:].copy(),
                    cooperative=self._coop[iid],
                )
            )
        return out
