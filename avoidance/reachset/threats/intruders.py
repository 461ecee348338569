"""Intruders (spec §5.4, (6.116)-(6.151), A-29, A-31): linear prediction in the LCF (and, with a
give-way turn rate, a right-turning one as well, D-21 of docs/reachset.md) and three
space-intersection models (line, body volume, manoeuvre-uncertainty elliptic cone), each with
its time-intersection rate against the UAS entry/leave window of the cell.

Times are relative to the grid's origin time (the next decision time t_{i+1}) [s]; positions LCF
[m]. Line and body are rated by exact point-to-cell distances of centre samples spaced in
proportion to the cell size (the pairs of samples and cells that lower bounds of the distance
allow, vectorised over intruders, in bounded blocks); the
cone is a weighted point cloud binned per cell. Intruders that cannot reach the grid within the
horizon are skipped exactly.
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


def predicted_positions(pos: np.ndarray, vel: np.ndarray, t: np.ndarray, right_turn_rate: float) -> np.ndarray:
    """LCF positions [m] at the times ``t`` [s] of intruders at ``pos`` [m] with velocity ``vel``
    [m/s] at t = 0 (``pos``, ``vel`` (..., 3) broadcast against ``t`` (...)): on the straight line
    if ``right_turn_rate`` is 0, else turning right (clockwise seen from above, LCF z up) at that
    rate [rad/s] at constant speed and climb rate."""
    t = np.asarray(t, float)[..., None]
    if right_turn_rate == 0.0:
        return pos + t * vel
    a = right_turn_rate * t[..., 0]
    s, k = np.sin(a) / right_turn_rate, (1.0 - np.cos(a)) / right_turn_rate
    vx, vy, vz = vel[..., 0], vel[..., 1], vel[..., 2]
    return pos + np.stack([vx * s + vy * k, vy * s - vx * k, vz * t[..., 0]], axis=-1)


def prediction_rates(give_way_turn_rate: float) -> tuple[float, ...]:
    """Turn rates [rad/s] of the predictions of every intruder: the straight line, and with
    ``give_way_turn_rate`` > 0 a right turn at that rate (giving way by the rules of the air, D-21)."""
    return (0.0, give_way_turn_rate) if give_way_turn_rate > 0.0 else (0.0,)


class IntruderModel:
    """Combined intruder model (6.150/6.151) for one grid and one reach set's UAS windows.

    Line and body (6.122-6.128) are rated exactly against the cells: the centre ``x(τ)`` is
    sampled every ``path_step`` layer depths of the path, and a cell is hit at τ when its exact
    distance to ``x(τ)`` (:meth:`AvoidanceGrid.distance`) is at most the body radius plus half
    the sample spacing, so the sampled balls cover the swept body; ``[i_e, i_l]`` is the hull of
    the hit times (every ball point carries its centre's time). With ``give_way_turn_rate`` > 0
    the centre is sampled on the straight and on the right-turning prediction, and hits and times
    are the union over both (D-21). With ``vertical_margin`` every centre sample is copied up
    and down over ± the margin (at most ``path_step`` apart, the bound grown by half that
    spacing): the swept body becomes a vertical capsule. The line is the body of radius 0, inside the body in space and
    time, so with the body on its rate never exceeds the body's and only the body is rated. The
    cone (6.129-6.149) keeps its lattice at ``spacing``. Intruders whose reachable volume within
    the horizon (the capsule of the model's radius around the predicted segment, or with the turn
    the ball of the path length) misses the grid's bounding ball are skipped: their rating is 0.
    """

    max_block = 1 << 20  # distance entries evaluated at once (memory bound per decision)

    def __init__(self, grid: AvoidanceGrid, uas_entry: np.ndarray, uas_leave: np.ndarray, cfg: IntruderModelConfig):
        self.grid, self.cfg = grid, cfg
        self.u_e, self.u_l = uas_entry, uas_leave
        self.horizon = float(uas_leave.max(initial=0.0)) + cfg.time_error
        self.step = cfg.path_step * float(grid.steps[0])

    def _bin(self, pts: np.ndarray, toa: np.ndarray, weight: np.ndarray | None = None):
        """Per cell: summed weight, earliest and latest time of arrival of lattice points."""
        cells = self.grid.cell_index(pts)
        ok = cells >= 0
        c, t = cells[ok], toa[ok]
        mass = np.bincount(c, weights=None if weight is None else weight[ok], minlength=self.grid.n_cells)
        i_e = np.full(self.grid.n_cells, np.inf)
        i_l = np.full(self.grid.n_cells, -np.inf)
        np.minimum.at(i_e, c, t)
        np.maximum.at(i_l, c, t)
        return mass, i_e, i_l

    def _rate(self, space: np.ndarray, i_e: np.ndarray, i_l: np.ndarray, speed: np.ndarray | float) -> np.ndarray:
        """Space rate × time rate (6.120); ``speed`` per row of ``space`` [m/s]."""
        if not self.cfg.timed:
            return space
        speed = np.asarray(speed, float)[..., None]
        tol = self.cfg.time_error + np.where(speed > 0, self.grid.steps[0] / np.maximum(speed, 1e-12), 0.0)
        return space * _time_rate(i_e, i_l, self.u_e - tol, self.u_l + tol)

    def _samples(self, speed: float) -> int:
        """Centre samples over the horizon: at most ``step`` apart, at least both ends."""
        return max(2, int(np.ceil(speed * self.horizon / self.step)) + 1)

    def _vertical_offsets(self) -> tuple[np.ndarray, float]:
        """Vertical offsets [m] of the centre copies spanning ``vertical_margin`` (at most
        ``step`` apart; one copy at 0 without it) and half their spacing [m]."""
        margin = self.cfg.vertical_margin
        if margin <= 0.0:
            return np.zeros(1), 0.0
        n = int(np.ceil(2.0 * margin / self.step)) + 1
        return np.linspace(-margin, margin, n), margin / (n - 1)

    def reach(self, motion: np.ndarray) -> np.ndarray:
        """(n,) radius [m] around each predicted segment within which the models can rate a cell."""
        cfg = self.cfg
        speed = np.linalg.norm(motion[:, 3:6], axis=1)
        n_t = np.array([self._samples(s) for s in speed])
        offsets, half_gap = self._vertical_offsets()
        out = np.where(cfg.body, motion[:, 6], 0.0) + 0.5 * speed * self.horizon / (n_t - 1)
        out = out + offsets[-1] + half_gap
        if not (cfg.line or cfg.body):
            out = np.full(len(motion), -np.inf)
        if cfg.spread:
            cone = max(np.sin(cfg.theta_i), np.sin(cfg.phi_i)) * speed * self.horizon + cfg.spacing
            out = np.maximum(out, cone)
        return out

    def reachable(self, motion: np.ndarray) -> np.ndarray:
        """(n,) whether each intruder's reachable volume within the horizon meets the grid's
        bounding ball (origin, radius = grid range): exact distance of the predicted segment
        x_s + v·τ, τ ∈ [0, horizon], to the origin against range + :meth:`reach`; with a give-way
        turn rate also |x_s| − |v|·horizon, a lower bound of the turning prediction's distance."""
        x, v = motion[:, :3], motion[:, 3:6]
        vv = np.einsum("ij,ij->i", v, v)
        with np.errstate(invalid="ignore", divide="ignore"):
            tau = np.clip(np.where(vv > 0, -np.einsum("ij,ij->i", x, v) / vv, 0.0), 0.0, self.horizon)
        gap = np.linalg.norm(x + tau[:, None] * v, axis=1)
        if self.cfg.give_way_turn_rate > 0.0:  # the turning prediction stays in the ball of its path length
            gap = np.minimum(gap, np.linalg.norm(x, axis=1) - np.sqrt(vv) * self.horizon)
        return gap <= self.grid.range + self.reach(motion) + 1e-9 * (1.0 + self.grid.range)  # rounding

    def ratings(self, motion: np.ndarray) -> np.ndarray:
        """(n_intruders, n_cells) P_OI of the linear predictions ``motion`` (:func:`intruder_motion`);
        rows of intruders that cannot reach the grid are 0."""
        out = np.zeros((len(motion), self.grid.n_cells))
        rows = np.flatnonzero(self.reachable(motion))
        if not len(rows):
            return out
        m = motion[rows]
        speed = np.linalg.norm(m[:, 3:6], axis=1)
        if self.cfg.line or self.cfg.body:
            out[rows] = self._rate(*self._body(m, speed), speed)
        if self.cfg.spread:
            for r, mm, sp in zip(rows, m, speed, strict=True):
                if sp > 0:
                    np.maximum(out[r], self._cone(mm[:3], mm[3:6], float(sp)), out=out[r])
        return out

    def _body(self, motion: np.ndarray, speed: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Hit indicator and hit-time hull [i_e, i_l] per (intruder, cell) of the swept bodies:
        the centre samples of all intruders are stacked, those farther from the whole grid than
        their bound dropped, and the rest's (sample, cell) pairs within the bound found
        (:meth:`AvoidanceGrid.near`) in blocks of at most :attr:`max_block` sample-cell entries,
        reduced per intruder and cell."""
        n, n_cells = len(motion), self.grid.n_cells
        n_t = np.array([self._samples(s) for s in speed])
        owner = np.repeat(np.arange(n), n_t)
        first = np.cumsum(n_t) - n_t
        tau = (np.arange(len(owner)) - first[owner]) * (self.horizon / (n_t[owner] - 1))
        rates = prediction_rates(self.cfg.give_way_turn_rate)
        centres = np.concatenate([predicted_positions(motion[owner, :3], motion[owner, 3:6], tau, r) for r in rates])
        owner, tau = np.tile(owner, len(rates)), np.tile(tau, len(rates))
        offsets, half_gap = self._vertical_offsets()  # the capsule: copies of every centre up and down
        centres = (centres[:, None, :] + offsets[None, :, None] * np.array([0.0, 0.0, 1.0])).reshape(-1, 3)
        owner, tau = np.repeat(owner, len(offsets)), np.repeat(tau, len(offsets))
        bound = (
            (motion[owner, 6] if self.cfg.body else 0.0)
            + 0.5 * speed[owner] * self.horizon / (n_t[owner] - 1)
            + half_gap
        )
        hit = np.zeros((n, n_cells))
        i_e = np.full((n, n_cells), np.inf)
        i_l = np.full((n, n_cells), -np.inf)
        keep = self.grid.envelope_distance(centres) <= bound  # samples that can touch any cell
        owner, tau, centres, bound = owner[keep], tau[keep], centres[keep], bound[keep]
        per_block = max(1, self.max_block // n_cells)
        for lo in range(0, len(owner), per_block):
            sl = slice(lo, lo + per_block)
            rows, cells = self.grid.near(centres[sl], bound[sl])
            key, t = owner[sl][rows] * n_cells + cells, tau[sl][rows]
            hit.flat[key] = 1.0
            np.minimum.at(i_e.reshape(-1), key, t)
            np.maximum.at(i_l.reshape(-1), key, t)
        return hit, i_e, i_l

    def _cone(self, x_s: np.ndarray, v: np.ndarray, speed: float) -> np.ndarray:
        """Elliptic cone (6.129-6.149): P_S = mean over the time samples in [i_e, i_l] of the
        ellipse mass in the cell; line samples every ``spacing``."""
        cfg = self.cfg
        n_t = max(3, int(np.ceil(speed * self.horizon / cfg.spacing)) + 1)
        tau = np.linspace(0.0, self.horizon, n_t)
        line = x_s + tau[:, None] * v
        e2, e3 = _perpendicular_basis(v / speed)
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
