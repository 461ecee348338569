"""Estimated future aircraft states and the free estimated state space (seed 002, 3.2-3.3).

Frames/units: (north, east) [m], times [s].

From an initial state (p_in, t_in) the aircraft's estimated future states at constant speed V
(wind compensated, V_G = V_T) are the isochrones |p - p_in| = V (t - t_in), the approximate
future states of 3.2 taken continuously in course. A state is in conflict when it lies inside
the obstacle at its time. Over planning interval j the obstacle is the timeline's envelope E_j,
and the states of that interval form the annulus A_j between the isochrones of t_j and t_j+1, so
the estimated obstacle region is exactly

    EX_obs(x_in) = U_j (A_j n E_j)          (the union of the estimated conflict areas, eq. 3.6)

computed with shapely's vectorised intersection instead of the thesis's sampled states (same
set, no course sampling). Annuli are polygons that circumscribe their outer isochrone and are
inscribed in their inner one, so neighbouring annuli overlap and no state is missed. Beyond the
timeline's last level the last envelope is held. The free space is EX_free = W \\ EX_obs (3.7),
kept to the connected parts that contain or touch p_in. Every straight segment from p_in inside EX_free
is a conflict-free trajectory at speed V: along it, time and range grow together.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import Point, Polygon
from shapely.geometry.base import BaseGeometry

from guidance.mptp.timeline import ObstacleTimeline
from guidance.mptp.visibility import Boundary, boundary_of

TOUCH_M = 1.0  # parts of the free space closer than this to p_in count as touching it [m]
MAX_RINGS = 40  # annuli per EX_obs (beyond, an annulus spans several planning intervals)


@dataclass(frozen=True, slots=True)
class FreeSpace:
    """EX_free(x_in) and its boundary; ``obstacle`` is EX_obs(x_in); ``trapped`` when p_in was
    inside EX_obs and an escape disc had to be carved (see :func:`free_space`)."""

    p_in: np.ndarray
    t_in: float
    free: BaseGeometry
    obstacle: BaseGeometry
    boundary: Boundary
    trapped: bool


def annuli(p: np.ndarray, radii: np.ndarray, segments: int) -> np.ndarray:
    """Polygons between consecutive radii around p: hole inscribed in radii[k], shell
    circumscribing radii[k+1]; the first one (radii[0] == 0) is a disc."""
    ang = np.linspace(0.0, 2 * math.pi, segments, endpoint=False)
    unit = np.stack([np.cos(ang), np.sin(ang)], 1)
    shells = shapely.linearrings(p + radii[1:, None, None] * unit[None] / math.cos(math.pi / segments))
    holes = shapely.linearrings(p + radii[1:-1, None, None] * unit[None, ::-1])
    return np.concatenate([shapely.polygons(shells[:1]), shapely.polygons(shells[1:], holes=holes[:, None])])


def obstacle_region(
    tl: ObstacleTimeline,
    p_in: np.ndarray,
    t_in: float,
    reach_m: float,
    speed: float,
    segments: int,
    permanent: bool = False,
) -> BaseGeometry:
    """EX_obs(x_in) out to range ``reach_m`` [m] (beyond the last level the last envelope).

    At most about MAX_RINGS annuli: when more planning intervals lie within reach (small dt),
    an annulus spans k consecutive intervals (groups aligned to multiples of k, so their
    envelopes are shared between expansions) with the envelope over the whole span, a superset
    of the per-interval pieces (conservative).

    ``permanent``: instead, the part of it that no later arrival escapes: each annulus cut with
    the intersection of its envelope and every later one to the end of the timeline (whose
    last level is held). A point in it is inside the envelope at every time it can be reached
    from x_in, waiting or not."""
    j0 = int(tl.interval(t_in))
    n = math.ceil(reach_m / (speed * tl.dt)) + 1
    k = max(1, math.ceil(n / MAX_RINGS))
    j_last = min(tl.n_levels - 1, j0 + n)
    first = (j0 // k + 1) * k
    ends = np.arange(first, max(first, j_last) + k, k)  # outer levels of the annuli
    radii = np.concatenate([[0.0], speed * (tl.level_time(ends) - t_in)])
    radii = radii[np.r_[True, radii[1:] < reach_m]]
    radii = np.append(radii, max(reach_m, radii[-1]) * 1.05 + 1.0)
    rings = annuli(p_in, radii, segments)
    starts = np.r_[j0, ends][: len(rings)]
    stops = np.r_[ends, ends[-1] + k][: len(rings)]
    env = tl.envelopes(starts, stops)
    if permanent:
        env = _suffix_intersections(tl, env, int(stops[-1]), k)
    hit = shapely.intersects(env, rings)  # the envelopes first: they are prepared
    if not hit.any():
        return Polygon()
    return polygonal(shapely.union_all(shapely.intersection(rings[hit], env[hit])))


def polygonal(geom: BaseGeometry) -> BaseGeometry:
    """The areal part of ``geom``: the polygons of a collection, dropping the lines and points
    that intersections of touching shapes leave (they have no area to avoid)."""
    if geom.geom_type != "GeometryCollection":
        return geom
    parts = [p for p in shapely.get_parts(geom) if p.geom_type in ("Polygon", "MultiPolygon")]
    return shapely.union_all(parts) if parts else Polygon()


def _suffix_intersections(tl: ObstacleTimeline, env: np.ndarray, stop: int, k: int) -> np.ndarray:
    """env[i] cut with env[i+1:] and with the envelopes of the levels from ``stop`` to the end
    of the timeline in spans of k (the intersection of an envelope with all later ones)."""
    tail_starts = np.arange(stop, tl.n_levels, k)
    tail = shapely.intersection_all(tl.envelopes(tail_starts, tail_starts + k)) if len(tail_starts) else None
    out = np.empty(len(env), object)
    acc = tail
    for i in range(len(env) - 1, -1, -1):
        acc = env[i] if acc is None else shapely.intersection(env[i], acc)
        out[i] = acc
    return out


def free_space(
    tl: ObstacleTimeline,
    p_in: np.ndarray,
    t_in: float,
    workspace: Polygon,
    speed: float,
    segments: int,
    escape_m: float = 0.0,
    permanent: bool = False,
) -> FreeSpace:
    """EX_free(x_in) = W \\ EX_obs(x_in), the part connected to p_in.

    With ``escape_m`` > 0, a p_in inside EX_obs is added to the free space as the thesis does
    when the aircraft is suddenly trapped inside a margin (and for the states of its way out,
    or a state a rounding error inside): a disc around p_in
    reaching ``escape_m`` [m] (one flyable leg) beyond the nearest free point is removed from
    EX_obs, so that the search can leave the margin the shortest way. ``permanent``: with the
    obstacle that no later arrival escapes (see :func:`obstacle_region`), for the SSPH."""
    p_in = np.asarray(p_in, float)
    reach = _reach(p_in, workspace)
    obs = obstacle_region(tl, p_in, t_in, reach, speed, segments, permanent)
    pt = Point(p_in)
    trapped = escape_m > 0 and obs.contains(pt)
    if trapped:
        obs = obs.difference(pt.buffer(obs.boundary.distance(pt) + escape_m, quad_segs=8))
    free = workspace.difference(obs)
    parts = shapely.get_parts(free)
    if len(parts) > 1:  # keep the parts p_in is in or on: the others cannot be reached
        near = shapely.distance(parts, pt)
        free = shapely.multipolygons(parts[near <= max(near.min(), 0.0) + TOUCH_M])
    return FreeSpace(p_in, t_in, free, obs, boundary_of(free), bool(trapped))


def _reach(p: np.ndarray, workspace: Polygon) -> float:
    """Largest distance from p to the workspace's bounding box corners [m]."""
    x0, y0, x1, y1 = workspace.bounds
    corners = np.array([[x0, y0], [x0, y1], [x1, y0], [x1, y1]])
    return float(np.linalg.norm(corners - p, axis=1).max())
