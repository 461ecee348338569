"""Avoidance Grid geometry (spec §3): polar cells in the LCF, vectorised cell lookup, and the
per-cell geometry used by the threat ratings (centres, outer cells, zones, horizontal
footprints, altitude offsets, volume samples).

Frame: LCF (X+ heading, Y+ left, Z+ up) [m]; angles [rad]. Flat cell index
``c = ((i-1)·J + (j-1))·K + (k-1)`` with 1-based layer i, column j (j=1 rightmost), row k (k=1 bottom);
arrays of per-cell values reshape to (I, J, K).
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
import shapely

from avoidance.reachset.config import GridConfig
from avoidance.reachset.frames import from_polar, to_polar

DEFAULT_GRID = GridConfig()


class AvoidanceGrid:
    """Geometry only; ratings live in per-decision arrays of length ``n_cells``."""

    def __init__(self, cfg: GridConfig = DEFAULT_GRID):
        self.cfg = cfg
        self.shape = (cfg.n_layers, cfg.n_h, cfg.n_v)
        self.n_cells = cfg.n_layers * cfg.n_h * cfg.n_v
        self.starts = np.array([cfg.d_range[0], cfg.theta_range[0], cfg.phi_range[0]])
        ends = np.array([cfg.d_range[1], cfg.theta_range[1], cfg.phi_range[1]])
        self.steps = (ends - self.starts) / np.array(self.shape)
        ijk = np.stack(np.unravel_index(np.arange(self.n_cells), self.shape), axis=1)  # 0-based
        self.ijk0 = ijk
        self.lower = self.starts + ijk * self.steps  # (n_cells, 3) polar lower bounds (open)
        self.upper = self.lower + self.steps  # polar upper bounds (closed)
        self.layer = ijk[:, 0]  # 0-based layer of each cell
        self.centers_polar = 0.5 * (self.lower + self.upper)
        self.centers = from_polar(self.centers_polar)
        self.outer = (
            (ijk[:, 0] == cfg.n_layers - 1)
            | np.isin(ijk[:, 1], (0, cfg.n_h - 1))
            | np.isin(ijk[:, 2], (0, cfg.n_v - 1))
        )
        self.zone = np.where(
            ijk[:, 0] < cfg.safe_layers, 0, np.where(ijk[:, 0] >= cfg.n_layers - cfg.crash_layers, 2, 1)
        )

    @property
    def range(self) -> float:
        return float(self.cfg.d_range[1])

    def cell_index_polar(self, dtp: np.ndarray) -> np.ndarray:
        """Flat cell index of polar points (..., 3), -1 outside (bounds (start, end], A-6)."""
        rel = np.ceil((dtp - self.starts) / self.steps - self.cfg.eps).astype(np.int64) - 1
        ok = np.all((rel >= 0) & (rel < np.array(self.shape)), axis=-1) & (dtp[..., 0] > self.starts[0])
        flat = (rel[..., 0] * self.shape[1] + rel[..., 1]) * self.shape[2] + rel[..., 2]
        return np.where(ok, flat, -1)

    def cell_index(self, p_lcf: np.ndarray) -> np.ndarray:
        """Flat cell index of Cartesian LCF points (..., 3), -1 outside the grid."""
        return self.cell_index_polar(to_polar(p_lcf))

    def distance(self, p_lcf: np.ndarray) -> np.ndarray:
        """Exact Euclidean distance [m] of LCF points (M, 3) to every cell (M, n_cells) (0 inside).

        A cell is the set of ``s·a`` with ``s`` in its distance band [d0, d1] and ``a`` a unit
        direction in its angular rectangle A = [θ0, θ1] × [φ0, φ1]. The distance of a point at range
        ρ to the segment s·a grows with the angle α between them, so the nearest direction of A is
        the one of least angle: its meridian is the circularly nearest θ of [θ0, θ1] (for every
        elevation ψ, cos α = cos φ cos ψ cos Δθ + sin φ sin ψ grows with cos Δθ), and on that
        meridian cos α = R cos(ψ − ψ*) is largest at ψ* clipped to [φ0, φ1] when ψ* lies inside,
        else at an end. Then s = clip(ρ cos α, d0, d1) and |p − s·a|² = (ρ cos α − s)² + ρ² sin² α."""
        return _polar_box_distance(p_lcf, *self._bounds()).reshape(-1, self.n_cells)

    def _bounds(self) -> tuple[np.ndarray, ...]:
        """Lower and upper θ of the columns (J,), φ of the rows (K,), d of the layers (I,)."""
        cfg = self.cfg
        th_lo = self.starts[1] + self.steps[1] * np.arange(cfg.n_h)
        ph_lo = self.starts[2] + self.steps[2] * np.arange(cfg.n_v)
        d_lo = self.starts[0] + self.steps[0] * np.arange(cfg.n_layers)
        return th_lo, th_lo + self.steps[1], ph_lo, ph_lo + self.steps[2], d_lo, d_lo + self.steps[0]

    def near(self, p_lcf: np.ndarray, bound: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The (point, cell) pairs of LCF points (M, 3) and cells whose exact distance
        (:meth:`distance`) is at most the point's ``bound`` (M,) [m]: (rows, flat cells), the
        same pairs as ``distance(p) <= bound[:, None]``. The exact distance is evaluated only
        where two lower bounds of it allow: the radial |ρ − clip(ρ, d0, d1)| per layer and the
        angular ρ sin α (ρ beyond 90°) per column and row."""
        th_lo, th_hi, ph_lo, ph_hi, d_lo, d_hi = self._bounds()
        rho, th, ph = to_polar(np.asarray(p_lcf, float).reshape(-1, 3)).T
        bound = np.asarray(bound, float)
        slack = bound * (1.0 + 1e-12) + 1e-12  # the lower bounds never reject a pair the exact test keeps
        cos_a = _nearest_cos(th, ph, th_lo, th_hi, ph_lo, ph_hi)  # (M, J, K)
        r = rho[:, None]
        radial = np.maximum(np.maximum(d_lo - r, r - d_hi), 0.0) <= slack[:, None]  # (M, I)
        across = np.where(cos_a >= 0.0, r[:, :, None] ** 2 * (1.0 - cos_a * cos_a), r[:, :, None] ** 2)
        angular = across <= (slack**2)[:, None, None]  # (M, J, K)
        m, i, j, k = np.nonzero(radial[:, :, None, None] & angular[:, None, :, :])
        d = _band_distance(rho[m], cos_a[m, j, k], d_lo[i], d_hi[i])
        keep = d <= bound[m]
        return m[keep], ((i[keep] * self.shape[1] + j[keep]) * self.shape[2] + k[keep])

    def envelope_distance(self, p_lcf: np.ndarray) -> np.ndarray:
        """Exact distance [m] of LCF points (M, 3) to the whole grid (the union of its cells) (M,);
        a lower bound of :meth:`distance` to every cell."""
        lo, hi = self.starts, self.starts + self.steps * np.array(self.shape)
        return _polar_box_distance(p_lcf, *([np.array([a]) for a in (lo[1], hi[1], lo[2], hi[2], lo[0], hi[0])]))[
            :, 0, 0, 0
        ]

    def wall_distance(self, p_lcf: np.ndarray, cells: np.ndarray) -> np.ndarray:
        """Distance of points to the 4 side walls (constant θ, constant φ) of their cells (§4.5)."""
        d, th, ph = to_polar(p_lcf).T
        lo, hi = self.lower[cells], self.upper[cells]
        dth = np.minimum(np.abs(th - lo[:, 1]), np.abs(th - hi[:, 1]))
        dph = np.minimum(np.abs(ph - lo[:, 2]), np.abs(ph - hi[:, 2]))
        return np.minimum(d * np.cos(ph) * np.sin(dth), d * np.sin(dph))

    def face_area(self, r: np.ndarray, cells: np.ndarray) -> np.ndarray:
        """Area of the spherical face at range ``r`` spanned by the cells' angles (6.93/6.94)."""
        lo, hi = self.lower[cells], self.upper[cells]
        return r * r * (hi[:, 1] - lo[:, 1]) * (np.sin(hi[:, 2]) - np.sin(lo[:, 2]))

    @cached_property
    def volume(self) -> np.ndarray:
        """Exact cell volumes [m³]."""
        lo, hi = self.lower, self.upper
        return (hi[:, 0] ** 3 - lo[:, 0] ** 3) / 3 * (hi[:, 1] - lo[:, 1]) * (np.sin(hi[:, 2]) - np.sin(lo[:, 2]))

    @cached_property
    def z_band(self) -> np.ndarray:
        """(n_cells, 2) min/max height of each cell relative to the LCF origin [m]."""
        z = np.stack(
            [
                self.lower[:, 0] * np.sin(self.lower[:, 2]),
                self.lower[:, 0] * np.sin(self.upper[:, 2]),
                self.upper[:, 0] * np.sin(self.lower[:, 2]),
                self.upper[:, 0] * np.sin(self.upper[:, 2]),
            ],
            axis=1,
        )
        return np.stack([z.min(axis=1), z.max(axis=1)], axis=1)

    @cached_property
    def footprints(self) -> np.ndarray:
        """(n_cells,) shapely polygons: horizontal LCF footprint of each cell, an annular sector
        ρ ∈ [d_s·cos φ_far, d_e·cos φ_near], θ ∈ [θ_s, θ_e] (spec §5.3), arcs ≤ ``arc_step``."""
        lo, hi = self.lower, self.upper
        cos_near = np.where(
            (lo[:, 2] <= 0) & (hi[:, 2] >= 0), 1.0, np.cos(np.minimum(np.abs(lo[:, 2]), np.abs(hi[:, 2])))
        )
        cos_far = np.cos(np.maximum(np.abs(lo[:, 2]), np.abs(hi[:, 2])))
        rho_in, rho_out = lo[:, 0] * cos_far, hi[:, 0] * cos_near
        n_arc = max(2, int(np.ceil(self.steps[1] / np.radians(2.0))) + 1)
        th = lo[:, 1:2] + (hi[:, 1] - lo[:, 1])[:, None] * np.linspace(0.0, 1.0, n_arc)[None, :]
        outer = np.stack([rho_out[:, None] * np.cos(th), rho_out[:, None] * np.sin(th)], axis=-1)
        inner = np.stack([rho_in[:, None] * np.cos(th), rho_in[:, None] * np.sin(th)], axis=-1)[:, ::-1]
        rings = np.concatenate([outer, inner], axis=1)
        return shapely.polygons(rings)

    @cached_property
    def volume_samples(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Polar lattice of ``samples_per_axis``³ points per cell: LCF points (M, 3), their cell
        (M,), and the volume each represents (M,) [m³] (sums to the cell volume)."""
        n = self.cfg.samples_per_axis
        u = (np.arange(n) + 0.5) / n
        uu = np.stack(np.meshgrid(u, u, u, indexing="ij"), axis=-1).reshape(-1, 3)
        dtp = self.lower[:, None, :] + uu[None, :, :] * self.steps  # (n_cells, n³, 3)
        w = dtp[..., 0] ** 2 * np.cos(dtp[..., 2])
        w = w / w.sum(axis=1, keepdims=True) * self.volume[:, None]
        cells = np.repeat(np.arange(self.n_cells), n**3)
        return from_polar(dtp).reshape(-1, 3), cells, w.reshape(-1)

    def per_cell(self, values: np.ndarray) -> np.ndarray:
        """View of a per-cell array as (I, J, K)."""
        return values.reshape(self.shape)


def _nearest_cos(
    th: np.ndarray, ph: np.ndarray, th_lo: np.ndarray, th_hi: np.ndarray, ph_lo: np.ndarray, ph_hi: np.ndarray
) -> np.ndarray:
    """cos α of the least angle α between the directions (θ, φ) of points (M,) and the angular
    rectangles [θ_lo, θ_hi] × [φ_lo, φ_hi] of the columns (J,) and rows (K,): (M, J, K)
    (derivation: :meth:`AvoidanceGrid.distance`)."""
    inside = (th[:, None] >= th_lo) & (th[:, None] <= th_hi)
    cos_dth = np.where(inside, 1.0, np.maximum(np.cos(th[:, None] - th_lo), np.cos(th[:, None] - th_hi)))  # (M, J)
    a = (np.cos(ph)[:, None] * cos_dth)[:, :, None]  # (M, J, 1)
    b = np.sin(ph)[:, None, None]
    psi = np.arctan2(b, a)
    best = np.where(
        (psi >= ph_lo) & (psi <= ph_hi),
        np.hypot(a, b),
        np.maximum(a * np.cos(ph_lo) + b * np.sin(ph_lo), a * np.cos(ph_hi) + b * np.sin(ph_hi)),
    )
    return np.clip(best, -1.0, 1.0)


def _band_distance(r: np.ndarray, cos_a: np.ndarray, d_lo: np.ndarray, d_hi: np.ndarray) -> np.ndarray:
    """Distance [m] of a point at range ``r`` to the segment [d_lo, d_hi] of a direction at
    angle α to it (broadcast): |p − s·a|² = (r cos α − s)² + r² sin² α, s = clip(r cos α, d_lo, d_hi)."""
    s = np.clip(r * cos_a, d_lo, d_hi)
    d2 = (r * cos_a - s) ** 2 + r * r * (1.0 - cos_a * cos_a)  # along + across the direction
    return np.sqrt(np.maximum(d2, 0.0))


def _polar_box_distance(
    p_lcf: np.ndarray,
    th_lo: np.ndarray,
    th_hi: np.ndarray,
    ph_lo: np.ndarray,
    ph_hi: np.ndarray,
    d_lo: np.ndarray,
    d_hi: np.ndarray,
) -> np.ndarray:
    """Distance [m] of LCF points (M, 3) to the polar boxes [d_lo, d_hi] × [θ_lo, θ_hi] ×
    [φ_lo, φ_hi] of every combination of the bands (I,), columns (J,) and rows (K,): (M, I, J, K)
    (derivation: :meth:`AvoidanceGrid.distance`)."""
    rho, th, ph = to_polar(np.asarray(p_lcf, float).reshape(-1, 3)).T
    cos_a = _nearest_cos(th, ph, th_lo, th_hi, ph_lo, ph_hi)[:, None, :, :]  # (M, 1, J, K)
    return _band_distance(rho[:, None, None, None], cos_a, d_lo[:, None, None], d_hi[:, None, None])
