"""Visibility in the free estimated state space (seed 002, 4.1.2), vectorised with numpy.

Frames/units: points (north, east) [m]. The free space is a shapely (Multi)Polygon; its rings are
oriented so that the free space is on the right (exterior clockwise, holes counter-clockwise),
i.e. the obstacle is on the left of every boundary edge, whether the obstacle is a storm region
or the outside of the workspace (the thesis's reversed mission-area ring).

- Tangent test (the thesis's M_pa / M_na matrices): a segment from s to vertex v is tangent at v
  when the previous and next vertices of v lie on the same side of the line s-v (or on it).
- Only convex obstacle corners (left turn with the obstacle on the left) can be on a shortest
  path; reflex vertices are dropped (4.1.2).
- Memory: the pairwise tests (every candidate against every edge its bounding box meets, every
  convex vertex against every other) run in blocks of at most MAX_PAIRS pairs, so a boundary
  of many vertices costs time, not memory that grows with the square of its size.
- Visibility: a candidate segment is visible when no boundary edge crosses it away from its two
  end points (crossings through an edge's end point count, so passing exactly through a vertex
  is conservatively blocked) and its midpoint lies in the free space (on its boundary counts).
  A segment that crosses no edge lies wholly on one side, so the midpoint decides the cases
  that counting intersections misses: a chord between two corners of the same convex obstacle
  (tangent at both ends) and a leg from a boundary point straight into the obstacle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

END_TOL_M = 1e-3  # crossings closer than this to a candidate's end points are ignored [m]
MAX_PAIRS = 2_000_000  # (segment, edge) or (vertex, vertex) pairs held in memory at once
GRAPH_PAIR_BUDGET = 100_000_000  # (segment, edge) pairs one reduced visibility graph may test


class OverBudget(RuntimeError):
    """A reduced visibility graph would test more than GRAPH_PAIR_BUDGET (segment, edge) pairs."""


@dataclass(frozen=True, slots=True)
class Boundary:
    """Boundary of a free space: convex corner vertices with their neighbours, and all edges."""

    verts: np.ndarray  # (V, 2) convex corners
    prev: np.ndarray  # (V, 2)
    next: np.ndarray  # (V, 2)
    ea: np.ndarray  # (E, 2) edge starts
    eb: np.ndarray  # (E, 2) edge ends
    tree: shapely.STRtree  # of the edges, for bounding-box pre-selection
    free: BaseGeometry  # the free space (prepared), for the midpoint test

    @property
    def n_edges(self) -> int:
        return len(self.ea)


def boundary_of(free: BaseGeometry) -> Boundary:
    """Vertices and edges of ``free`` ((Multi)Polygon), obstacle on the left of every edge."""
    free = shapely.orient_polygons(free, exterior_cw=True)
    rings = shapely.get_rings(shapely.get_parts(free))
    coords, idx = shapely.get_coordinates(rings, return_index=True)
    keep = np.ones(len(coords), bool)
    keep[np.r_[np.flatnonzero(np.diff(idx)), len(idx) - 1]] = False  # drop the closing points
    pts, ring = coords[keep], idx[keep]
    start = np.r_[0, np.flatnonzero(np.diff(ring)) + 1]
    count = np.diff(np.r_[start, len(ring)])
    local = np.arange(len(ring)) - np.repeat(start, count)
    base, n = np.repeat(start, count), np.repeat(count, count)
    prv, nxt = pts[base + (local - 1) % n], pts[base + (local + 1) % n]
    turn = _cross(pts - prv, nxt - pts)
    convex = turn > 0
    tree = shapely.STRtree(shapely.linestrings(np.stack([pts, nxt], 1)))
    shapely.prepare(free)
    return Boundary(pts[convex], prv[convex], nxt[convex], pts, nxt, tree, free)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def tangent(src: np.ndarray, b: Boundary, cols: np.ndarray | slice = slice(None)) -> np.ndarray:
    """(S, V) bool: the segment from each source to each convex vertex (of ``cols``, an index
    or slice of them) is tangent at the vertex."""
    verts = b.verts[cols]
    d = verts[None, :, :] - src[:, None, :]
    c1 = _cross(d, (b.prev[cols] - verts)[None])
    c2 = _cross(d, (b.next[cols] - verts)[None])
    return c1 * c2 >= 0.0


def blocked(p: np.ndarray, q: np.ndarray, b: Boundary, budget: float = math.inf) -> np.ndarray:
    """(C,) bool: segment p_i -> q_i is crossed by a boundary edge away from its end points, or
    its midpoint is outside the free space (by more than END_TOL_M: the midpoint of a segment
    along a boundary edge is a rounding error off it). ``budget``: see first_hit."""
    mid = 0.5 * (p + q)
    out = first_hit(p, q, b, budget) < np.inf
    near = ~out & ~shapely.contains_xy(b.free, mid[:, 0], mid[:, 1])  # inside: distance 0
    out[near] = ~shapely.dwithin(b.free, shapely.points(mid[near]), END_TOL_M)
    return out


def first_hit(p: np.ndarray, q: np.ndarray, b: Boundary, budget: float = math.inf) -> np.ndarray:
    """(C,) fraction along p -> q of the first boundary crossing (inf when none). Edges are
    pre-selected by bounding box (STRtree), then intersected exactly in one numpy pass per
    block of candidates (a block meets at most MAX_PAIRS edges). Raises OverBudget when the
    (candidate, edge) pairs tested exceed ``budget``."""
    out = np.full(len(p), np.inf)
    if not len(p) or not b.n_edges:
        return out
    step = max(1, MAX_PAIRS // b.n_edges)
    tested = 0
    for k in range(0, len(p), step):
        ci, ei = b.tree.query(shapely.linestrings(np.stack([p[k : k + step], q[k : k + step]], 1)))
        tested += len(ci)
        if tested > budget:
            raise OverBudget(f"more than {budget:.0f} (segment, edge) pairs on a boundary of {b.n_edges} edges")
        out[k : k + step] = _first_hit(p[k : k + step], q[k : k + step], b, ci, ei)
    return out


def _first_hit(p: np.ndarray, q: np.ndarray, b: Boundary, ci: np.ndarray, ei: np.ndarray) -> np.ndarray:
    """first_hit of one block of candidates, whose pre-selected (candidate, edge) pairs are
    ``ci``, ``ei``."""
    out = np.full(len(p), np.inf)
    if not len(ci):
        return out
    pp, r = p[ci], q[ci] - p[ci]
    s = b.eb[ei] - b.ea[ei]
    w = b.ea[ei] - pp
    den = _cross(r, s)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = _cross(w, s) / den  # along the candidate
        v = _cross(w, r) / den  # along the edge
    tol = END_TOL_M / np.maximum(np.linalg.norm(r, axis=1), END_TOL_M)
    hit = (np.abs(den) > 1e-12) & (u > tol) & (u < 1.0 - tol) & (v >= 0.0) & (v <= 1.0)
    np.minimum.at(out, ci[hit], u[hit])
    return out


def visible_vertices(src: np.ndarray, b: Boundary) -> tuple[np.ndarray, np.ndarray]:
    """Visible tangent edges from sources: (source index, vertex index) arrays."""
    si, vi = np.nonzero(tangent(src, b))
    ok = ~blocked(src[si], b.verts[vi], b)
    return si[ok], vi[ok]


def reduced_graph(b: Boundary) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Edges (i, j, length) of the reduced visibility graph VG_r among the convex vertices:
    bitangent (tangent at both ends) and visible, each undirected edge once (i < j); the
    tangency matrix is built in blocks of rows of at most MAX_PAIRS entries. Raises OverBudget
    when its visibility tests would take more than GRAPH_PAIR_BUDGET (segment, edge) pairs."""
    n = len(b.verts)
    rows = max(1, MAX_PAIRS // max(n, 1))
    ii, jj = [np.empty(0, int)], [np.empty(0, int)]
    for r0 in range(0, n, rows):
        block = slice(r0, min(n, r0 + rows))
        both = tangent(b.verts[block], b) & tangent(b.verts, b, block).T  # (rows, n): at j and at i
        bi, bj = np.nonzero(np.triu(both, k=r0 + 1))
        ii.append(bi + r0)
        jj.append(bj)
    i, j = np.concatenate(ii), np.concatenate(jj)
    ok = ~blocked(b.verts[i], b.verts[j], b, GRAPH_PAIR_BUDGET)
    i, j = i[ok], j[ok]
    return i, j, np.linalg.norm(b.verts[j] - b.verts[i], axis=1)
