"""Synthetic storm nowcasts of the size of the thesis's Monte-Carlo study (seed 002, 6.2).

Frames/units: local-level NED (north, east) [m] from the thesis's origin 47.50 N, 10.25 E
(``mptp_thesis.ORIGIN``), velocities [m/s], times [s] from the nowcast issue.

The thesis ran its 10,000 trials on one Rad-TRAM nowcast (27 June 2015, 19:05 UTC) over the
mission area 47.50-50.00 N x 10.25-14.00 E (about 278 km x 275 km). That nowcast is not
available, so a field is drawn here with what the thesis states of it: cells moving at ground
speeds of 6.2-17.6 m/s on courses of 88.5-128.5 deg (its section 7 on the 19:05 nowcast), and a
number and size of cells chosen so that the margined cells cover on average about the thesis's
share of the mission area (18.2 % with 10 km margins at issue, 26.4 % with 20 km after one
hour; ``coverage`` measures it, docs/mptp.md gives the calibration).

A cell is a jagged ellipse (radial harmonics and per-vertex noise, like a Rad-TRAM polygon)
whose centre is uniform over the mission area widened by ``pad_m``; a nowcast translates every
cell with its velocity every ``step_s`` up to the horizon (no growth or decay foreseen, as a
Rad-TRAM nowcast). All cells of a field are built in one numpy pass.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import Polygon

from sim.core.threats import StormSnapshot


@dataclass(frozen=True, slots=True)
class FieldSpec:
    """Distribution of one synthetic nowcast: ``n_cells`` cells with semi-major axis uniform in
    ``radius_m`` [m] and minor/major ratio uniform in ``aspect``, speed uniform in ``speed_mps``
    and course uniform in ``course_deg`` (from north, positive east), centres uniform over the
    box ``bounds`` = (north_min, east_min, north_max, east_max) [m] widened by ``pad_m``;
    ``roughness`` scales the outline's harmonics and noise; ``n_vertices`` per outline."""

    bounds: tuple[float, float, float, float]
    n_cells: int = 12
    radius_m: tuple[float, float] = (4_000.0, 14_000.0)
    aspect: tuple[float, float] = (0.4, 1.0)
    speed_mps: tuple[float, float] = (6.2, 17.6)
    course_deg: tuple[float, float] = (88.5, 128.5)
    pad_m: float = 30_000.0
    roughness: float = 0.08
    n_vertices: int = 24

    def __post_init__(self) -> None:
        n0, e0, n1, e1 = self.bounds
        if not (n1 > n0 and e1 > e0):
            raise ValueError(f"bounds: expected (north_min, east_min, north_max, east_max), got {self.bounds}")
        for name in ("radius_m", "aspect", "speed_mps", "course_deg"):
            lo, hi = getattr(self, name)
            if not 0 <= lo <= hi:
                raise ValueError(f"{name}: expected 0 <= lo <= hi, got ({lo}, {hi})")
        if self.n_cells < 0 or self.n_vertices < 8 or self.aspect[0] <= 0 or self.pad_m < 0:
            raise ValueError("need n_cells >= 0, n_vertices >= 8, aspect > 0 and pad_m >= 0")


@dataclass(frozen=True, slots=True)
class Cells:
    """One drawn field at issue: outlines (N, V, 2) [m], velocities (N, 2) [m/s]."""

    outlines: np.ndarray
    velocities: np.ndarray

    @property
    def centres(self) -> np.ndarray:
        return self.outlines.mean(axis=1)

    @property
    def speeds(self) -> np.ndarray:
        return np.hypot(self.velocities[:, 0], self.velocities[:, 1])

    @property
    def courses_deg(self) -> np.ndarray:
        return np.degrees(np.arctan2(self.velocities[:, 1], self.velocities[:, 0])) % 360.0


def draw_cells(spec: FieldSpec, seed: int) -> Cells:
    """The cells of field ``seed`` at the issue time (independent streams per seed)."""
    rng = np.random.default_rng(np.random.SeedSequence([0x4D50, seed]))
    n, v = spec.n_cells, spec.n_vertices
    n0, e0, n1, e1 = spec.bounds
    centre = rng.uniform([n0 - spec.pad_m, e0 - spec.pad_m], [n1 + spec.pad_m, e1 + spec.pad_m], (n, 2))
    major = rng.uniform(*spec.radius_m, n)
    minor = major * rng.uniform(*spec.aspect, n)
    heading = rng.uniform(0.0, math.pi, n)
    speed = rng.uniform(*spec.speed_mps, n)
    course = np.radians(rng.uniform(*spec.course_deg, n))
    amp = rng.uniform(0.0, spec.roughness, (n, 3, 1))
    phase = rng.uniform(0.0, 2 * math.pi, (n, 3, 1))
    th = np.linspace(0.0, 2 * math.pi, v, endpoint=False)
    order = np.arange(2, 5)[None, :, None]
    r = 1.0 + (amp * np.cos(order * th + phase)).sum(axis=1) + rng.normal(0.0, 0.3 * spec.roughness, (n, v))
    x, y = major[:, None] * r * np.cos(th), minor[:, None] * r * np.sin(th)
    c, s = np.cos(heading)[:, None], np.sin(heading)[:, None]
    outlines = np.stack([c * x - s * y, s * x + c * y], axis=-1) + centre[:, None, :]
    velocities = speed[:, None] * np.stack([np.cos(course), np.sin(course)], axis=1)
    return Cells(outlines, velocities)


def nowcast(
    cells: Cells, t_issue: float = 0.0, horizon_s: float = 3600.0, step_s: float = 300.0
) -> list[StormSnapshot]:
    """Snapshots at t_issue + k step_s [s], k = 0 .. horizon/step: every cell moved with its
    velocity (cells are kept apart, as a nowcaster reports them; the planner merges margins)."""
    out = []
    for k in range(round(horizon_s / step_s) + 1):
        d = k * step_s
        rings = cells.outlines + cells.velocities[:, None, :] * d
        polys = shapely.polygons(rings) if len(rings) else np.empty(0, object)
        out.append(StormSnapshot(t_issue + d, tuple(shapely.make_valid(polys)), cells.velocities.copy()))
    return out


def coverage(cells: Cells, area: Polygon, margin_m: float, t: float) -> float:
    """Share of ``area`` covered by the cells' convex hulls at time ``t`` [s] (since issue)
    grown by ``margin_m`` [m] (the thesis's "mission area coverage")."""
    if not len(cells.outlines):
        return 0.0
    rings = cells.outlines + cells.velocities[:, None, :] * t
    hulls = shapely.convex_hull(shapely.polygons(rings))
    covered = shapely.union_all(shapely.buffer(hulls, margin_m, quad_segs=8))
    return float(covered.intersection(area).area / area.area)
