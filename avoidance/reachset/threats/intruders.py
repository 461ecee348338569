"""Intruders (spec §5.4, (6.116)-(6.151), A-29, A-31): linear prediction in the LCF and three
space-intersection models (line, body volume, manoeuvre-uncertainty elliptic cone), each with
its time-intersection rate against the UAS entry/leave window of the cell.

Times are relative to the grid's origin time (the next decision time t_{i+1}) [s]; positions LCF
[m]. A model is a point cloud (points, time of arrival, weight per time sample); all models are
binned with the same vectorised cell lookup.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from avoidance.reachset.config import IntruderModelConfig
from avoidance.reachset.frames import GridPose
from avoidance.reachset.grid import AvoidanceGrid
from sim.core.frames import ned_to_enu
from sim.core.threats import IntruderTrack


@lru_cache(maxsize=8)
def _unit_ball(step: float) -> np.ndarray:
    """Lattice points of the unit ball with spacing ``step`` (plus the centre)."""
    u = np.arange(-1.0, 1.0 + 1e-9, step)
    p = np.stack(np.meshgrid(u, u, u, indexing="ij"), axis=-1).reshape(-1, 3)
    return p[np.einsum("ij,ij->i", p, p) <= 1.0 + 1e-9]


@lru_cache(maxsize=8)
def _unit_disc(steps: int, ratio: float, density: str) -> tuple[np.ndarray, np.ndarray]:
    """Lattice of the unit disc (u1, u2) and normalised weights of the cone density (6.133-6.136,
    6.144) for semi-axes with ratio d_θ/d_φ = ``ratio`` (the weights do not depend on the scale)."""
    u = np.linspace(-1.0, 1.0, steps)
    p = np.stack(np.meshgrid(u, u, indexing="ij"), axis=-1).reshape(-1, 2)
    p = p[np.einsum("ij,ij->i", p, p) <= 1.0 + 1e-9]
    g1 = np.exp(-0.5 * p[:, 0] ** 2)  # N(u1·dθ; 0, dθ) ∝ exp(-u1²/2) / dθ
    g2 = np.exp(-0.5 * p[:, 1] ** 2)
    w = g1 * g2 if density == "product" else 0.5 * (g1 / ratio + g2)  # dθ = ratio·dφ, common 1/dφ dropped
    return p, w / w.sum()


def _perpendicular_basis(e1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal (intruder-local Y) and vertical (local Z) unit axes of the plane ⊥ ``e1``."""
    e2 = np.cross([0.0, 0.0, 1.0], e1)
    n = np.linalg.norm(e2)
    e2 = e2 / n if n > 1e-9 else np.array([0.0, 1.0, 0.0])
    return e2, np.cross(e1, e2)


def _time_rate(i_e: np.ndarray, i_l: np.ndarray, u_e: np.ndarray, u_l: np.ndarray) -> np.ndarray:
    """(6.119) with the indicator for an instantaneous UAS window (A-31)."""
    span = u_l - u_e
    overlap = np.clip(np.minimum(i_l, u_l) - np.maximum(i_e, u_e), 0.0, None)
    inst = ((u_e >= i_e) & (u_e <= i_l)).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(span > 1e-9, overlap / span, inst)


class IntruderModel:
    """Combined intruder model (6.150/6.151) for one grid and one reach set's UAS windows."""

    def __init__(self, grid: AvoidanceGrid, uas_entry: np.ndarray, uas_leave: np.ndarray, cfg: IntruderModelConfig):
        self.grid, self.cfg = grid, cfg
        self.u_e, self.u_l = uas_entry, uas_leave
        self.horizon = float(uas_leave.max(initial=0.0)) + cfg.time_error

    def _bin(self, pts: np.ndarray, toa: np.ndarray, weight: np.ndarray | None = None):
        """Per cell: summed weight (or hit indicator), earliest and latest time of arrival."""
        cells = self.grid.cell_index(pts)
        ok = cells >= 0
        c, t = cells[ok], toa[ok]
        mass = np.bincount(c, weights=None if weight is None else weight[ok], minlength=self.grid.n_cells)
        i_e = np.full(self.grid.n_cells, np.inf)
        i_l = np.full(self.grid.n_cells, -np.inf)
        np.minimum.at(i_e, c, t)
        np.maximum.at(i_l, c, t)
        return mass, i_e, i_l

    def _rate(self, space: np.ndarray, i_e: np.ndarray, i_l: np.ndarray, speed: float) -> np.ndarray:
        if not self.cfg.timed:
            return space
        tol = self.cfg.time_error + (self.grid.steps[0] / speed if speed > 0 else 0.0)  # [R] tolerance
        return space * _time_rate(i_e, i_l, self.u_e - tol, self.u_l + tol)

    def rating(self, x_s: np.ndarray, v: np.ndarray, radius: float) -> np.ndarray:
        """P_OI per cell (n_cells,) of an intruder at ``x_s`` (LCF, at the grid time) with
        velocity ``v`` (LCF) [m/s] and body ``radius`` [m]."""
        cfg = self.cfg
        speed = float(np.linalg.norm(v))
        n_t = max(3, int(np.ceil(speed * self.horizon / cfg.spacing)) + 1)
        tau = np.linspace(0.0, self.horizon, n_t)
        line = x_s + tau[:, None] * v
        out = np.zeros(self.grid.n_cells)
        if cfg.line:
            hit, i_e, i_l = self._bin(line, tau)
            np.maximum(out, self._rate((hit > 0).astype(float), i_e, i_l, speed), out=out)
        if cfg.body:
            pts, toa = self._swept_ball(line, tau, v, radius)
            hit, i_e, i_l = self._bin(pts, toa)
            np.maximum(out, self._rate((hit > 0).astype(float), i_e, i_l, speed), out=out)
        if cfg.spread and speed > 0:
            np.maximum(out, self._cone(line, tau, v / speed, speed), out=out)
        return out

    def _swept_ball(self, line: np.ndarray, tau: np.ndarray, v: np.ndarray, radius: float):
        """Body volume (6.125-6.128): the ball swept along the line, sampled as a disc ⊥ v at
        every line sample plus full balls at both ends; every point keeps its centre's time."""
        ball = _unit_ball(min(1.0, self.cfg.spacing / max(radius, 1e-9))) * radius
        speed = float(np.linalg.norm(v))
        if speed == 0.0:
            return (line[:1] + ball), np.zeros(len(ball))
        e2, e3 = _perpendicular_basis(v / speed)
        disc = ball[np.abs(ball[:, 2]) < 1e-9][:, :2]
        sweep = line[:, None, :] + disc[None, :, 0:1] * e2 + disc[None, :, 1:2] * e3
        pts = np.concatenate([sweep.reshape(-1, 3), line[0] + ball, line[-1] + ball])
        toa = np.concatenate([np.repeat(tau, len(disc)), np.full(len(ball), tau[0]), np.full(len(ball), tau[-1])])
        return pts, toa

    def _cone(self, line: np.ndarray, tau: np.ndarray, e1: np.ndarray, speed: float) -> np.ndarray:
        """Elliptic cone (6.129-6.149): P_S = mean over the time samples in [i_e, i_l] of the
        ellipse mass in the cell."""
        cfg = self.cfg
        e2, e3 = _perpendicular_basis(e1)
        ratio = np.sin(cfg.theta_i) / np.sin(cfg.phi_i)
        disc, w = _unit_disc(cfg.cone_steps, float(ratio), cfg.density)
        dd = speed * tau
        a, b = np.sin(cfg.theta_i) * dd, np.sin(cfg.phi_i) * dd
        pts = line[:, None, :] + (
            a[:, None, None] * disc[None, :, 0:1] * e2 + b[:, None, None] * disc[None, :, 1:2] * e3
        )
        toa = np.repeat(tau, len(disc))
        mass, i_e, i_l = self._bin(pts.reshape(-1, 3), toa, np.tile(w, len(tau)))
        dt = tau[1] - tau[0]
        n_samples = np.where(np.isfinite(i_e), np.rint((i_l - i_e) / dt) + 1, 1.0)
        return self._rate(np.minimum(mass / n_samples, 1.0), i_e, i_l, speed)


def intruder_motion(pose: GridPose, t_grid: float, tracks: list[IntruderTrack], body_margin: float) -> np.ndarray:
    """(n_intruders, 7) linear predictions of the tracks (NED) at the grid time ``t_grid`` [s]:
    LCF position [m], LCF velocity [m/s], body radius + ``body_margin`` [m]."""
    out = np.zeros((len(tracks), 7))
    for n, tr in enumerate(tracks):
        pos = np.asarray(tr.pos_ned, float) + np.asarray(tr.vel_ned, float) * (t_grid - tr.t)
        out[n] = [*pose.ned_to_lcf(pos), *pose.vec_to_lcf(ned_to_enu(tr.vel_ned)), tr.radius_m + body_margin]
    return out


def intruder_ratings(grid: AvoidanceGrid, motion: np.ndarray, model: IntruderModel) -> np.ndarray:
    """(n_intruders, n_cells) P_OI of the intruders' linear predictions ``motion``
    (:func:`intruder_motion`)."""
    out = np.zeros((len(motion), grid.n_cells))
    for n, m in enumerate(motion):
        out[n] = model.rating(m[:3], m[3:6], float(m[6]))
    return out
