"""Seeded synthetic storm fields, since no real nowcast can be downloaded here.

Frames/units: (north, east) [m], velocities [m/s], times [s].

A cell is a jagged blob (an ellipse with random radial harmonics and per-vertex noise, like
the jagged Rad-TRAM polygons) whose centre drifts with a constant velocity and whose size
follows a life cycle: growth from 40 % to full size in the first third of its life, mature,
decay to 40 % in the last third, then it dies. A cell may split once: at its split time it is
replaced by two children of half its area drifting apart sideways at 20-50 % of the mean drift
speed each (2-5 m/s for a 10 m/s field; proportional, so that a field scaled in space and time
keeps its shapes). Cells that overlap at a time are merged (union) in the snapshot, with the
area-weighted mean velocity.

``truth(t)`` is the storm field at any time. ``nowcast(t_issue)`` is what a Rad-TRAM-like
nowcaster issues at t_issue: the cells observed then, extrapolated with their velocities every
``step`` seconds up to the horizon (no growth, decay or splitting foreseen), so nowcast and truth
diverge with lead time as in the thesis's Fig. 6.1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import Polygon

from sim.core.threats import StormSnapshot


@dataclass(frozen=True, slots=True)
class Cell:
    centre: np.ndarray  # (2,) at t = born [m]
    velocity: np.ndarray  # (2,) [m/s]
    axes: tuple[float, float]  # semi-axes at full size [m]
    heading: float  # ellipse orientation [rad]
    harmonics: np.ndarray  # (H, 2) relative amplitude and phase of radial harmonics
    noise: np.ndarray  # (n_vertices,) per-vertex radial noise
    born: float
    life: float
    split_at: float | None = None  # time of splitting (inf = never)

    def scale(self, t: float) -> float:
        a = (t - self.born) / self.life
        if a < 0 or a > 1:
            return 0.0
        return 0.4 + 0.6 * min(1.0, 3 * a, 3 * (1 - a))

    def polygon(self, t: float) -> Polygon | None:
        s = self.scale(t)
        if s <= 0:
            return None
        n = len(self.noise)
        th = np.linspace(0, 2 * math.pi, n, endpoint=False)
        r = 1.0 + self.noise + sum(h[0] * np.cos((k + 2) * th + h[1]) for k, h in enumerate(self.harmonics))
        x, y = s * self.axes[0] * r * np.cos(th), s * self.axes[1] * r * np.sin(th)
        c, si = math.cos(self.heading), math.sin(self.heading)
        pts = np.stack([c * x - si * y, si * x + c * y], 1) + self.centre + self.velocity * (t - self.born)
        return Polygon(pts)


@dataclass
class StormField:
    """A storm field in the box [0, size_n] x [0, size_e] [m] with ``n_cells`` cells.

    Cells drift with ``mean_velocity`` [m/s] plus a spread of ``speed_spread`` [m/s]; their
    mean semi-axis is ``mean_radius_m``; ``n_vertices`` per cell outline; ``split_prob`` chance
    that a cell splits; lives of ``life_s`` [s] on average, born over [t0 - life, t0 + span]."""

    seed: int = 0
    n_cells: int = 12
    size_m: tuple[float, float] = (250_000.0, 250_000.0)
    mean_velocity: tuple[float, float] = (0.0, 10.0)
    speed_spread: float = 3.0
    mean_radius_m: float = 8_000.0
    n_vertices: int = 36
    split_prob: float = 0.3
    life_s: float = 5400.0
    t0: float = 0.0
    span_s: float = 3600.0
    centres: np.ndarray | None = None  # (n_cells, 2) [m]: place the cells here (t = t0) instead
    births_after_t0: bool = True  # False: every cell is alive at t0 (no cell pops up unforeseen)
    extent_up_m: tuple[float, float] = (-math.inf, math.inf)  # [base, top] of every cell above the origin [m]

    def __post_init__(self) -> None:
        rng = np.random.default_rng(self.seed)
        self.cells: list[Cell] = [self._random_cell(rng) for _ in range(self.n_cells)]
        if self.centres is not None:
            self.cells = [self._placed(c, np.asarray(x, float)) for c, x in zip(self.cells, self.centres, strict=False)]
        children = []
        for c in self.cells:
            if c.split_at is not None:
                children += self._split(c, c.split_at, rng)
        self.cells += children

    def _random_cell(self, rng: np.random.Generator) -> Cell:
        life = self.life_s * rng.uniform(0.7, 1.3)
        late = self.t0 + 0.3 * self.span_s if self.births_after_t0 else self.t0 - 0.1 * life
        born = rng.uniform(self.t0 - 0.6 * life, late)
        r = self.mean_radius_m * rng.uniform(0.5, 1.5)
        split = born + life * rng.uniform(0.4, 0.6) if rng.uniform() < self.split_prob else None
        return Cell(
            centre=rng.uniform([0, 0], self.size_m),
            velocity=np.array(self.mean_velocity) + rng.normal(0, self.speed_spread, 2),
            axes=(r, r * rng.uniform(0.5, 1.0)),
            heading=rng.uniform(0, math.pi),
            harmonics=np.stack([rng.uniform(0, 0.12, 3), rng.uniform(0, 2 * math.pi, 3)], 1),
            noise=rng.normal(0, 0.03, self.n_vertices),
            born=born,
            life=life,
            split_at=split,
        )

    def _placed(self, c: Cell, centre_at_t0: np.ndarray) -> Cell:
        """The same cell moved so that its centre is at ``centre_at_t0`` at t0."""
        return Cell(
            centre_at_t0 - c.velocity * (self.t0 - c.born),
            c.velocity,
            c.axes,
            c.heading,
            c.harmonics,
            c.noise,
            c.born,
            c.life,
            c.split_at,
        )

    def _split(self, c: Cell, t: float, rng: np.random.Generator) -> list[Cell]:
        """Two children continuing from the split time ``t`` [s] with half the area each."""
        centre = c.centre + c.velocity * (t - c.born)
        side = np.array([-c.velocity[1], c.velocity[0]]) / (np.linalg.norm(c.velocity) + 1e-9)
        k = 1 / math.sqrt(2)
        scale = c.scale(t)
        life = 1.5 * (c.life - (t - c.born))  # born mature: a third of the life has passed at t
        drift = float(np.hypot(*self.mean_velocity))
        return [
            Cell(
                centre=centre + sgn * side * c.axes[1] * 0.5 * scale - (c.velocity + sgn * side * dv) * life / 3,
                velocity=c.velocity + sgn * side * dv,
                axes=(c.axes[0] * k * scale, c.axes[1] * k * scale),
                heading=c.heading,
                harmonics=c.harmonics,
                noise=rng.normal(0, 0.03, self.n_vertices),
                born=t - life / 3,
                life=life,
            )
            for sgn, dv in ((1.0, rng.uniform(0.2, 0.5) * drift), (-1.0, rng.uniform(0.2, 0.5) * drift))
        ]

    def cell_shapes(self, t: float) -> tuple[list[Polygon], np.ndarray, np.ndarray]:
        """Live cells at time t (before merging), their velocities (N, 2) [m/s] and vertical
        extents (N, 2) [base, top] [m]."""
        shapes, vel = [], []
        for c in self.cells:
            if c.split_at is not None and t >= c.split_at:
                continue
            p = c.polygon(t)
            if p is not None:
                shapes.append(p)
                vel.append(c.velocity)
        return shapes, np.array(vel).reshape(-1, 2), np.tile(np.asarray(self.extent_up_m, float), (len(shapes), 1))

    def truth(self, t: float) -> StormSnapshot:
        """The storm field at time t with overlapping cells merged."""
        return merge_cells(t, *self.cell_shapes(t))

    def nowcast(self, t_issue: float, horizon_s: float = 3600.0, step_s: float = 300.0) -> list[StormSnapshot]:
        """Snapshots at t_issue + k step: observed cells extrapolated with their velocities."""
        observed, vel, ext = _union(*self.cell_shapes(t_issue))
        out = []
        for k in range(round(horizon_s / step_s) + 1):
            d = k * step_s
            cells = tuple(shapely.affinity.translate(c, *(vel[i] * d)) for i, c in enumerate(observed))
            out.append(StormSnapshot(t_issue + d, cells, vel.copy(), ext.copy()))
        return out


def merge_cells(t: float, shapes: list[Polygon], velocities: np.ndarray, extents: np.ndarray) -> StormSnapshot:
    """Union overlapping cells into one, with the area-weighted mean velocity and the lowest
    base and highest top of its parts."""
    return StormSnapshot(t, *_union(shapes, velocities, extents))


def _union(
    shapes: list[Polygon], velocities: np.ndarray, extents: np.ndarray
) -> tuple[tuple[Polygon, ...], np.ndarray, np.ndarray]:
    """Overlapping cells unioned, their area-weighted mean velocities (N, 2) [m/s] and vertical
    extents (N, 2) [base, top] [m] (lowest base, highest top of the parts)."""
    if not shapes:
        return (), np.zeros((0, 2)), np.zeros((0, 2))
    arr = np.asarray(shapes, object)
    merged = shapely.get_parts(shapely.union_all(arr))
    tree = shapely.STRtree(arr)
    area = shapely.area(arr)
    vel = np.zeros((len(merged), 2))
    ext = np.zeros((len(merged), 2))
    for m, geom in enumerate(merged):
        idx = tree.query(geom, predicate="intersects")
        vel[m] = (area[idx, None] * velocities[idx]).sum(0) / area[idx].sum()
        ext[m] = extents[idx, 0].min(), extents[idx, 1].max()
    return tuple(merged), vel, ext
