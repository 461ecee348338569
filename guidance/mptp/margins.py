"""Margins around nowcast storm cells (seed 002, 3.1.1-3.1.5), in (north, east) [m].

- Cells are made convex first (concave radar signatures mean turbulence and hail, 3.1.1).
- Probabilistic margin: circles at the vertices with radius r(P, theta, t) = k(P) sigma(theta) t,
  where t is the lead time since the nowcast was issued [s], theta the angle between the cell's
  motion and the vector from its geometric centre to the vertex, sigma(theta) the assumed
  standard deviation [m/s] of the cell's displacement error per axis (largest along the motion,
  smallest against it) and k(P) = sqrt(-2 ln(1 - P)) the radius that holds a 2-D isotropic
  Gaussian error with probability P. The thesis takes r(P, theta, t) from a table of [70] that
  is not in the seed; this closed form has the same three properties (grows with t, largest in
  the moving direction, larger for larger P) and is bounded by ``prob_margin_max_m``.
- Safety margin: FAA-style clearance by cell speed band and by appearance (single cell or line
  of storms, Table 3.1, its wind-speed bands applied to the cell's speed: cells move with the
  wind of their steering level), plus an extra by the cell's area (``safety_area_steps``),
  independent of the lead time. On the downwind side it is ``downwind_factor`` f times the
  upwind one (3.1.2: turbulence and hail are frequently met downwind): around every vertex
  the safety reach in the offset direction phi is s (1 + (f - 1)(1 + cos phi) / 2), phi the
  angle between that direction and the downwind one (a limacon instead of a circle: s
  upwind, f s downwind, (1 + f) s / 2 across). The downwind direction is the wind's (the
  planner's forecast) or, in still air, the cell's motion.
- The two are superimposed by adding their radii (ch. 6: "the sum of safety and probabilistic
  margins"); the margin polygon is the convex hull of the cell and all circles, each circle a
  circumscribed polygon so that the hull contains the true discs.
- Inflation: ``extra_m`` is added to every radius (Douglas-Peucker tolerance, fly-by corner cut).
- Merging (union) and clustering (closing passages narrower than eps, 3.1.4) keep the concave
  shapes they produce (3.1.5: never re-convexified).
"""

from __future__ import annotations

import math

import numpy as np
import shapely
from shapely.geometry import Polygon
from shapely.geometry.base import BaseGeometry

from guidance.mptp.config import MptpConfig
from guidance.mptp.turnmodel import exit_offset_m

CIRCLE_SEGMENTS = 16
SPEED_BANDS_MPS = (10.0, 20.0)


def probability_factor(p: float) -> float:
    """k(P) with P(|e| <= k sigma) = P for a 2-D isotropic Gaussian error e (Rayleigh)."""
    return math.sqrt(-2.0 * math.log1p(-p))


def safety_margin_m(
    speed_mps: np.ndarray, is_line: np.ndarray, cfg: MptpConfig, area_m2: np.ndarray | None = None
) -> np.ndarray:
    """Safety clearance [m] per cell from its speed band and appearance (Table 3.1), plus the
    extra of its area step [m^2] (``safety_area_steps``; none when ``area_m2`` is None)."""
    band = np.searchsorted(SPEED_BANDS_MPS, np.asarray(speed_mps, float), side="right")
    base = np.where(is_line, np.take(cfg.safety_line_m, band), np.take(cfg.safety_single_m, band))
    if area_m2 is None or not cfg.safety_area_steps:
        return base
    steps = np.asarray(cfg.safety_area_steps)
    k = np.searchsorted(steps[:, 0] * 1e6, np.asarray(area_m2, float), side="right")
    return base + np.concatenate([[0.0], steps[:, 1]])[k]


def downwind_scale(directions: np.ndarray, downwind: np.ndarray, factor: float) -> np.ndarray:
    """Factor on the safety margin in the offset ``directions`` (K, 2) (unit vectors): 1 against
    the ``downwind`` direction (2,) (any length; zero = no wind, 1 everywhere), ``factor`` along
    it, 1 + (factor - 1)(1 + cos phi) / 2 in between (a limacon, convex for factor <= 3)."""
    norm = float(np.hypot(*downwind))
    if factor == 1.0 or norm < 1e-9:
        return np.ones(len(directions))
    cos_p = (directions @ downwind) / (np.linalg.norm(directions, axis=1) * norm)
    return 1.0 + (factor - 1.0) * 0.5 * (1.0 + cos_p)


def is_line_of_storms(hulls: np.ndarray, aspect: float) -> np.ndarray:
    """True for cells whose minimum rotated rectangle is at least ``aspect`` times longer than wide."""
    rect = shapely.oriented_envelope(hulls)
    out = np.zeros(len(hulls), bool)
    for i, r in enumerate(rect):
        c = np.asarray(r.exterior.coords) if isinstance(r, Polygon) else None
        if c is not None and len(c) >= 4:
            a, b = float(np.linalg.norm(c[1] - c[0])), float(np.linalg.norm(c[2] - c[1]))
            out[i] = max(a, b) >= aspect * max(min(a, b), 1e-9)
    return out


def margin_hulls(
    cells: list[Polygon] | tuple[Polygon, ...],
    velocities_ne: np.ndarray | None,
    lead_s: float,
    cfg: MptpConfig,
    extra_m: float = 0.0,
    wind_ne: np.ndarray | None = None,
) -> np.ndarray:
    """Convex margin polygon of every cell at lead time ``lead_s`` [s] (array of Polygons);
    ``wind_ne`` (north, east) [m/s] the wind whose downwind side gets ``downwind_factor``
    (None or zero: each cell's motion)."""
    if len(cells) == 0:
        return np.empty(0, object)
    hulls = shapely.convex_hull(np.asarray(cells, object))
    vel = np.zeros((len(cells), 2)) if velocities_ne is None else np.asarray(velocities_ne, float).reshape(-1, 2)
    speed = np.hypot(vel[:, 0], vel[:, 1])
    safety = safety_margin_m(speed, is_line_of_storms(hulls, cfg.line_aspect), cfg, shapely.area(hulls))
    wind = np.zeros(2) if wind_ne is None else np.asarray(wind_ne, float).reshape(2)
    k = probability_factor(cfg.probability) * max(lead_s, 0.0)
    ang = np.linspace(0.0, 2 * math.pi, CIRCLE_SEGMENTS, endpoint=False)
    unit = np.stack([np.cos(ang), np.sin(ang)], 1) / math.cos(math.pi / CIRCLE_SEGMENTS)
    coords, owner = [], []
    centres = shapely.get_coordinates(shapely.centroid(hulls))
    for i, h in enumerate(hulls):
        v = np.asarray(h.exterior.coords)[:-1] if isinstance(h, Polygon) else shapely.get_coordinates(h)
        rel = v - centres[i]
        if speed[i] > 1e-9:
            cos_t = (rel @ vel[i]) / (np.linalg.norm(rel, axis=1) * speed[i] + 1e-12)
            sigma = cfg.sigma_back_mps + (cfg.sigma_front_mps - cfg.sigma_back_mps) * (1.0 + cos_t) / 2.0
        else:
            sigma = np.full(len(v), 0.5 * (cfg.sigma_front_mps + cfg.sigma_back_mps))
        r = safety[i] + np.minimum(k * sigma, cfg.prob_margin_max_m) + extra_m
        grow = safety[i] * (downwind_scale(unit, wind if wind.any() else vel[i], cfg.downwind_factor) - 1.0)
        pts = (v[:, None, :] + r[:, None, None] * unit[None] + grow[None, :, None] * unit[None]).reshape(-1, 2)
        coords.append(pts)
        owner.append(np.full(len(pts), i))
    return convex_hulls(np.vstack(coords), np.concatenate(owner))


def convex_hulls(points: np.ndarray, groups: np.ndarray) -> np.ndarray:
    """Convex hull of each group of ``points`` (K, 2) labelled by ``groups`` (K,) (sorted group
    indices 0..G-1, at least 2 points each). The groups go to GEOS as linestrings: the hull of
    the same coordinates in the same order as a multipoint's, without one point geometry per
    coordinate (~4x faster)."""
    return shapely.convex_hull(shapely.linestrings(points, indices=groups))


def merge(shapes: np.ndarray | list[BaseGeometry], cfg: MptpConfig) -> BaseGeometry:
    """Union of margin shapes, clustered (closing by ``cluster_eps_m``) and line-smoothed."""
    geom = shapely.union_all(np.asarray(shapes, object))
    if cfg.cluster_eps_m > 0 and not geom.is_empty:
        geom = close_gaps(geom, cfg.cluster_eps_m)
    if cfg.simplify_tol_m > 0:
        geom = shapely.simplify(geom, 0.5 * cfg.simplify_tol_m, preserve_topology=True)
    return geom


def close_gaps(geom: BaseGeometry, eps_m: float) -> BaseGeometry:
    """Morphological closing with a disc of diameter ``eps_m``: passages narrower than eps
    between shapes are filled, i.e. single-linkage clustering with linkage distance eps (what
    DBSCAN with np_min = 1 on a fine grid computes, 3.1.4), with the concave outline kept."""
    return geom.buffer(0.5 * eps_m, quad_segs=4).buffer(-0.5 * eps_m, quad_segs=4)


def turn_cut_m(cfg: MptpConfig) -> float:
    """How far the flown path strays from the planned legs [m]: a fly-by arc of the minimum
    radius cuts inside a corner of |dchi_max| by R (1/cos(dchi/2) - 1) (simple model); a fly-over
    turn runs outside its leg's chord by at most its exit offset (turnmodel.exit_offset_m)."""
    if cfg.turn_model != "simple":
        return exit_offset_m(cfg)
    return cfg.turn_radius_m * (1.0 / math.cos(0.5 * cfg.course_change_max) - 1.0)
