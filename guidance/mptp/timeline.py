"""Expected future obstacle locations: margined nowcast cells interpolated in space and time.

Frames/units: shapes in (north, east) [m]; times in sim seconds [s].

Spatio-temporal interpolation (seed 002, 3.1.6). Cells of consecutive nowcast steps are matched
by advection (the cell of step k moved by its velocity over the step overlaps the cell of step
k+1; one cell may match several, which covers splitting and merging). A matched pair of convex
margin polygons A, B is interpolated as the Minkowski combination (1-s) A + s B, s in [0, 1]:
it is convex, equals A and B at the ends, moves a translating cell linearly and grows a growing
one linearly. Its vertices are a fixed sequence lerped in s (edges of A and B merged by angle),
so every level is one vectorised shapely call. A cell without a successor is extrapolated with
its velocity; a cell without a predecessor is held at its first shape over the whole step
(conservative). After the last nowcast step cells are extrapolated with their velocities up to
the end of the horizon; beyond it the last level is held.

Planning levels are t_j = t_issue + j * dt. For the search, the obstacle over one planning
interval [t_j, t_j+1] is its *envelope*: the union over pairs of conv(shape(t_j) U shape(t_j+1))
(cut at nowcast steps), which contains every interpolated shape in the interval, so a state at
any time of the interval that is outside the envelope is outside the obstacle at that time.
"""

from __future__ import annotations

import itertools
import math
from functools import lru_cache
from typing import overload

import numpy as np
import shapely
from shapely import affinity
from shapely.geometry import Polygon
from shapely.geometry.base import BaseGeometry

from guidance.mptp.config import MptpConfig
from guidance.mptp.margins import convex_hulls, margin_hulls, merge, turn_cut_m
from sim.core.threats import StormSnapshot


def minkowski_sequences(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vertex sequences (CA, CB) of equal length such that (1-s) CA + s CB are the vertices of
    the Minkowski combination (1-s) A + s B of convex polygons A, B ((n, 2) open rings)."""
    return _merged(_Edges.of(a), _Edges.of(b))


class _Edges:
    """A convex ring counter-clockwise from its lowest vertex (``seq`` (n, 2)), its edges and
    their angles [rad] in [0, 2 pi): what the Minkowski merge needs of one polygon."""

    __slots__ = ("ang", "edges", "seq")

    def __init__(self, seq: np.ndarray):
        self.seq = seq
        self.edges = np.diff(np.vstack([seq, seq[:1]]), axis=0)
        self.ang = np.mod(np.arctan2(self.edges[:, 1], self.edges[:, 0]), 2 * math.pi)

    @classmethod
    def of(cls, ring: np.ndarray) -> _Edges:
        return cls(_from_lowest(_ccw(ring)))


def _merged(a: _Edges, b: _Edges) -> tuple[np.ndarray, np.ndarray]:
    """minkowski_sequences of two prepared rings."""
    order = np.argsort(np.concatenate([a.ang, b.ang]), kind="stable")
    from_a = order < len(a.edges)
    out = []
    for p, e, mine in ((a.seq, a.edges, from_a), (b.seq, b.edges, ~from_a)):
        step = np.zeros((len(order), 2))
        step[mine] = e
        out.append(p[0] + np.vstack([np.zeros((1, 2)), np.cumsum(step, axis=0)[:-1]]))
    return out[0], out[1]


def _ccw(p: np.ndarray) -> np.ndarray:
    x, y = p[:, 0], p[:, 1]
    area2 = np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))
    return p if area2 >= 0 else p[::-1]


def _from_lowest(p: np.ndarray) -> np.ndarray:
    i = np.lexsort((p[:, 0], p[:, 1]))[0]
    return np.roll(p, -i, axis=0)


def _ring(poly: Polygon) -> np.ndarray:
    return np.asarray(poly.exterior.coords)[:-1]


class ObstacleTimeline:
    """Margined storm cells of one nowcast as a function of time.

    ``snapshots``: the nowcast (first = issue time); ``t_end`` [s]: the last time the planner
    will ask about (cells are extrapolated up to it); ``cfg``: margins, dt and tolerances;
    ``drift_ne`` [m/s]: the velocity of the frame the shapes are given in (the wind, for the
    air-mass frame, see wind.py): a shape at time t is moved by -drift (t - t_issue). Margins
    and cell matching use the ground velocities of the nowcast; the drift is also the wind
    whose downwind side the safety margins grow on (margins.py).
    """

    def __init__(
        self, snapshots: list[StormSnapshot], cfg: MptpConfig, t_end: float, drift_ne: np.ndarray | None = None
    ):
        if not snapshots:
            raise ValueError("a timeline needs at least one nowcast snapshot")
        snaps = sorted(snapshots, key=lambda s: s.t)
        self.cfg = cfg
        self.t_issue = snaps[0].t
        self.drift = np.zeros(2) if drift_ne is None else np.asarray(drift_ne, float).reshape(2)
        self.dt = cfg.dt_s
        self.extra_m = cfg.simplify_tol_m + turn_cut_m(cfg)
        snaps = _extrapolate(snaps, t_end, cfg.dt_s * max(1, round(300.0 / cfg.dt_s)))
        self.snapshots = snaps
        self.times = np.array([s.t for s in snaps])
        hulls = [
            margin_hulls(s.cells, s.velocities_ne, s.t - self.t_issue, cfg, self.extra_m, self.drift) for s in snaps
        ]
        rings = [[_Edges.of(_ring(h)) for h in hs] for hs in hulls]  # each hull prepared once for all its pairs
        self._pairs = [
            self._interval_pairs(snaps[k], snaps[k + 1], rings[k], rings[k + 1]) for k in range(len(snaps) - 1)
        ] or [self._held_pairs(rings[0])]
        self.n_levels = math.ceil((max(t_end, self.times[-1]) - self.t_issue) / self.dt) + 1
        self.envelope_span = lru_cache(maxsize=None)(self._envelope_span)

    # --- construction -----------------------------------------------------------------------
    def _interval_pairs(self, a: StormSnapshot, b: StormSnapshot, ha: list[_Edges], hb: list[_Edges]):
        step = b.t - a.t
        va = _velocities(a)
        moved = np.array([affinity.translate(c, *(va[i] * step)) for i, c in enumerate(a.cells)], object)
        tree = shapely.STRtree(shapely.convex_hull(np.asarray(b.cells, object)))
        ia, jb = (
            tree.query(shapely.convex_hull(moved), predicate="intersects") if len(moved) else (np.empty(0, int),) * 2
        )
        pairs = [(ha[i], hb[j]) for i, j in zip(ia, jb, strict=False)]
        lost = np.setdiff1d(np.arange(len(a.cells)), ia)
        if len(lost):
            ext = margin_hulls(list(moved[lost]), va[lost], b.t - self.t_issue, self.cfg, self.extra_m, self.drift)
            pairs += [(ha[i], _Edges.of(_ring(q))) for i, q in zip(lost, ext, strict=False)]
        pairs += [(hb[j], hb[j]) for j in np.setdiff1d(np.arange(len(b.cells)), jb)]
        return self._pairset_of(a.t, b.t, [_merged(p, q) for p, q in pairs])

    def _held_pairs(self, h: list[_Edges]):
        return self._pairset_of(self.t_issue, self.t_issue, [_merged(p, p) for p in h])

    def _pairset_of(self, ta: float, tb: float, seqs: list[tuple[np.ndarray, np.ndarray]]) -> _PairSet:
        return _PairSet(ta, tb, seqs, self.drift, self.t_issue)

    # --- queries ------------------------------------------------------------------------------
    @overload
    def level_time(self, j: int) -> float: ...
    @overload
    def level_time(self, j: np.ndarray) -> np.ndarray: ...
    def level_time(self, j: int | np.ndarray) -> float | np.ndarray:
        """Start time [s] of planning interval(s) ``j``."""
        return self.t_issue + j * self.dt

    def interval(self, t: np.ndarray | float) -> np.ndarray:
        """Planning interval index of time(s) ``t``, clipped to [0, n_levels - 1]."""
        return np.clip(np.floor((np.asarray(t, float) - self.t_issue) / self.dt).astype(int), 0, self.n_levels - 1)

    def shape_at(self, t: float) -> BaseGeometry:
        """Merged margin region at time ``t`` [s] (what the aircraft must be outside of)."""
        return merge(self._pairset(t).polygons(t), self.cfg)

    def envelope(self, j: int) -> BaseGeometry:
        """Envelope of planning interval j (cached)."""
        return self.envelope_span(j, 1)

    def _envelope_span(self, j: int, k: int) -> BaseGeometry:
        """Envelope over the k planning intervals from level j, [t_j, t_j+k] (beyond the
        nowcast's last step its shapes are held, drifting with the frame)."""
        t0, t1 = self.level_time(j), self.level_time(j + k)
        cuts = np.concatenate([[t0], self.times[(self.times > t0) & (self.times < t1)], [t1]])
        hulls = [self._pairset(0.5 * (a + b)).swept_hulls(a, b) for a, b in itertools.pairwise(cuts)]
        env = merge(np.concatenate(hulls), self.cfg)
        shapely.prepare(env)  # cached and tested against many rings and footprints
        return env

    def _pairset(self, t: float) -> _PairSet:
        k = int(np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self._pairs) - 1))
        return self._pairs[k]

    def envelopes(self, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
        """Envelopes over the level spans [starts[i], ends[i]] (object array; levels past the
        end are held)."""
        last = self.n_levels - 1
        return np.array(
            [
                self.envelope_span(int(min(a, last)), int(max(1, min(b, last + 1) - min(a, last))))
                for a, b in zip(starts, ends, strict=False)
            ],
            object,
        )

    def contains(self, points: np.ndarray, times: np.ndarray) -> np.ndarray:
        """True where point (north, east) [m] is strictly inside the margin region at its time."""
        points, times = np.atleast_2d(points), np.atleast_1d(times)
        out = np.zeros(len(points), bool)
        for t in np.unique(times):
            m = times == t
            out[m] = shapely.contains_xy(self.shape_at(float(t)), points[m, 0], points[m, 1])
        return out


class _PairSet:
    """Matched pairs of one nowcast step [ta, tb]: vertex sequences lerped in s (held outside
    the step), moved by -drift (t - t_ref) (the frame's motion)."""

    def __init__(
        self, ta: float, tb: float, seqs: list[tuple[np.ndarray, np.ndarray]], drift: np.ndarray, t_ref: float
    ):
        self.ta, self.tb, self.drift, self.t_ref = ta, tb, drift, t_ref
        self.ca = np.vstack([a for a, _ in seqs]) if seqs else np.empty((0, 2))
        self.cb = np.vstack([b for _, b in seqs]) if seqs else np.empty((0, 2))
        self.owner = np.concatenate([np.full(len(a), i) for i, (a, _) in enumerate(seqs)]) if seqs else np.empty(0, int)

    def s(self, t: float) -> float:
        return 0.0 if self.tb <= self.ta else float(np.clip((t - self.ta) / (self.tb - self.ta), 0.0, 1.0))

    def coords(self, t: float) -> np.ndarray:
        s = self.s(t)
        return (1.0 - s) * self.ca + s * self.cb - self.drift * (t - self.t_ref)

    def polygons(self, t: float) -> np.ndarray:
        if not len(self.owner):
            return np.empty(0, object)
        return shapely.polygons(shapely.linearrings(self.coords(t), indices=self.owner))

    def swept_hulls(self, ta: float, tb: float) -> np.ndarray:
        """Convex hulls of every pair's shapes at ta and tb [s] (within one step both the lerp
        and the drift are linear in t, so they contain every shape in between)."""
        if not len(self.owner):
            return np.empty(0, object)
        pts = np.stack([self.coords(ta), self.coords(tb)], axis=1).reshape(-1, 2)
        return convex_hulls(pts, np.repeat(self.owner, 2))


def _velocities(s: StormSnapshot) -> np.ndarray:
    if s.velocities_ne is None:
        return np.zeros((len(s.cells), 2))
    return np.asarray(s.velocities_ne, float).reshape(len(s.cells), 2)


def _extrapolate(snaps: list[StormSnapshot], t_end: float, step: float) -> list[StormSnapshot]:
    """Append snapshots every ``step`` [s] after the last one, cells moved by their velocities,
    until ``t_end`` is covered (nothing is appended for cells without velocities)."""
    last = snaps[-1]
    if last.velocities_ne is None or not len(last.cells):
        return snaps
    v = _velocities(last)
    out = list(snaps)
    n = math.ceil((t_end - last.t) / step)
    for i in range(1, n + 1):
        d = i * step
        cells = tuple(affinity.translate(c, *(v[k] * d)) for k, c in enumerate(last.cells))
        out.append(StormSnapshot(last.t + d, cells, v.copy()))
    return out
