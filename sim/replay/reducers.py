"""Running reductions that metrics fold chunks of samples into, in O(1) memory.

Every reducer takes numpy chunks in time order and gives the same result however the samples are
split into chunks, except the float sums of :class:`RunningStats`, which are added per chunk
(live runs and replays cut the same chunks, so their sums are the same numbers).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field

import numpy as np


@dataclass
class RunningStats:
    """Count, mean, RMS and largest magnitude of a signal."""

    count: int = 0
    total: float = 0.0
    total_sq: float = 0.0
    max_abs: float = 0.0

    def add(self, x: np.ndarray) -> None:
        if x.size:
            self.count += int(x.size)
            self.total += float(np.sum(x))
            self.total_sq += float(np.sum(x * x))
            self.max_abs = max(self.max_abs, float(np.max(np.abs(x))))

    def result(self) -> dict[str, float]:
        if not self.count:
            return {"count": 0}
        return {
            "count": self.count,
            "mean": self.total / self.count,
            "rms": math.sqrt(self.total_sq / self.count),
            "max_abs": self.max_abs,
        }


@dataclass
class RunningMin:
    """The smallest value and its time [s] (the first time on ties), with optional values that
    go with it (e.g. the vertical separation at the smallest horizontal one)."""

    value: float | None = None
    t: float | None = None
    extra: tuple[float, ...] = ()

    def add(self, t: np.ndarray, x: np.ndarray, *extra: np.ndarray) -> None:
        if not x.size:
            return
        k = int(np.argmin(x))
        if self.value is None or float(x[k]) < self.value:
            self.value, self.t = float(x[k]), float(t[k])
            self.extra = tuple(float(e[k]) for e in extra)

    def distance(self) -> dict:
        """The minimum as a closest approach: ``distance_m`` [m] and ``t`` [s] (None: no sample)."""
        return {"distance_m": self.value, "t": self.t}


@dataclass
class CylinderSeparation:
    """From relative positions NED [m]: the smallest horizontal and vertical separations [m], the
    vertical one at the smallest horizontal one, and whether the pair was ever inside a cylinder
    (horizontal radius, vertical half height [m]) horizontally and vertically at one time."""

    nmac_h_m: float
    nmac_v_m: float
    well_clear_h_m: float
    well_clear_v_m: float
    horizontal: RunningMin = field(default_factory=RunningMin)
    min_vertical: float = math.inf
    nmac: bool = False
    lowc: bool = False

    def add(self, t: np.ndarray, rel_ned: np.ndarray) -> None:
        if not len(rel_ned):
            return
        h, v = np.hypot(rel_ned[:, 0], rel_ned[:, 1]), np.abs(rel_ned[:, 2])
        self.horizontal.add(t, h, v)
        self.min_vertical = min(self.min_vertical, float(v.min()))
        self.nmac |= bool(((h < self.nmac_h_m) & (v < self.nmac_v_m)).any())
        self.lowc |= bool(((h < self.well_clear_h_m) & (v < self.well_clear_v_m)).any())

    def result(self) -> dict:
        if self.horizontal.value is None:
            return {}
        return {
            "min_horizontal_m": self.horizontal.value,
            "vertical_at_min_horizontal_m": self.horizontal.extra[0],
            "min_vertical_m": self.min_vertical,
            "nmac": self.nmac,
            "lowc": self.lowc,
        }


@dataclass
class Intervals:
    """Intervals where a condition holds: start, end [s] and the smallest distance in each [m].
    One entry per interval, not per sample."""

    events: list[dict] = field(default_factory=list)
    _open: dict | None = None

    def add(self, t: np.ndarray, inside: np.ndarray, dist: np.ndarray) -> None:
        start = 0
        if self._open is not None:  # the interval open at the last chunk's end goes on
            start = t.size if inside.all() else int(np.argmin(inside))
            if start:
                self._open["min_distance_m"] = min(self._open["min_distance_m"], float(dist[:start].min()))
                self._open["end"] = float(t[start - 1])
            if start < t.size:
                self._open = None
        edges = start + np.flatnonzero(np.diff(np.concatenate([[0], inside[start:].astype(int), [0]])))
        for s, e in zip(edges[::2], edges[1::2], strict=True):
            ev = {"start": float(t[s]), "end": float(t[e - 1]), "min_distance_m": float(dist[s:e].min())}
            self.events.append(ev)
            self._open = ev if e == t.size else None

    def result(self) -> list[dict]:
        return [dict(e) for e in self.events]


LATENCY_EXACT = 4096  # values kept exactly; beyond, a log-spaced histogram
LATENCY_BIN_RATIO = 1.01  # histogram bin width: ±0.5 % relative error of a quantile
LATENCY_MIN_S = 1e-7  # histogram range [s] from this to 1000 s; values outside land in its end bins
LATENCY_BINS = math.ceil(math.log(1e3 / LATENCY_MIN_S) / math.log(LATENCY_BIN_RATIO)) + 1


@dataclass
class LatencySketch:
    """Median, 95th percentile and maximum of planner-call latencies [s].

    Exact (numpy's linear interpolation) for up to ``LATENCY_EXACT`` values; past that the values
    move into a histogram with bins ``LATENCY_BIN_RATIO`` wide in ratio, and a quantile is its
    bin's geometric centre: within ±0.5 % of an order statistic next to the exact quantile. The
    count and maximum stay exact. Memory is bounded by the histogram's ~2100 bins.
    """

    count: int = 0
    max_s: float = 0.0
    _values: list[float] | None = field(default_factory=list)
    _bins: np.ndarray | None = None

    def add(self, seconds: np.ndarray) -> None:
        if not seconds.size:
            return
        self.count += int(seconds.size)
        self.max_s = max(self.max_s, float(np.max(seconds)))
        if self._values is not None:
            self._values.extend(float(s) for s in seconds)
            if len(self._values) <= LATENCY_EXACT:
                return
            seconds, self._values = np.asarray(self._values), None
            self._bins = np.zeros(LATENCY_BINS, dtype=np.int64)
        assert self._bins is not None
        np.add.at(self._bins, self._bin(seconds), 1)

    @staticmethod
    def _bin(seconds: np.ndarray) -> np.ndarray:
        k = np.floor(np.log(np.maximum(seconds, LATENCY_MIN_S) / LATENCY_MIN_S) / math.log(LATENCY_BIN_RATIO))
        return np.clip(k, 0, LATENCY_BINS - 1).astype(np.int64)

    def quantile(self, q: float) -> float:
        """The ``q`` quantile (0..1) [s]."""
        if self._values is not None:
            return float(np.quantile(np.asarray(self._values), q))
        assert self._bins is not None
        k = bisect.bisect_left(np.cumsum(self._bins).tolist(), q * (self.count - 1) + 1)
        return min(LATENCY_MIN_S * LATENCY_BIN_RATIO ** (k + 0.5), self.max_s)
