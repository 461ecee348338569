"""Run metrics, folded in by streaming: the same accumulators serve live runs and log replay.

A live run feeds each vehicle's trace in chunks of ``CHUNK`` log ticks as it flies; a replay cuts
the logged trace into the same chunks, so both give the same numbers. Memory does not grow with
the run's duration. Per vehicle: :mod:`sim.replay.vehicle_metrics`; per pair:
:mod:`sim.replay.pair_metrics`; the world they are measured against:
:mod:`sim.replay.metrics_world`.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable

import numpy as np

from sim.replay.metrics_world import EMPTY_WORLD, MetricsWorld
from sim.replay.pair_metrics import PairMatcher, PairMetrics, common_times
from sim.replay.trace import CHUNK, VehicleTrace
from sim.replay.vehicle_metrics import VehicleMetrics

__all__ = ["MetricsWorld", "PairFn", "RunMetrics", "differing_keys", "flatten", "run_metrics"]

PairFn = Callable[[str, str, np.ndarray, np.ndarray], None]  # (a, b, common times [s], a - b NED [m])


class RunMetrics:
    """Every metric of a run, folded in chunk by chunk from each vehicle as it logs (live) or
    from the log (replay): the same chunks give the same numbers. ``on_pair`` sees each pair's
    samples as they are matched."""

    def __init__(self, world: MetricsWorld = EMPTY_WORLD, on_pair: PairFn | None = None):
        self.world = world
        self.on_pair = on_pair
        self.vehicles: dict[str, VehicleMetrics] = {}
        self.pairs: dict[tuple[str, str], tuple[PairMetrics, PairMatcher]] = {}

    def vehicle(self, name: str, kind: str) -> None:
        """Register a vehicle (pairs are named in registration order)."""
        for other in self.vehicles:
            pm = PairMetrics(self.world)
            self.pairs[(other, name)] = (pm, PairMatcher(self._pair_sink(pm, other, name)))
        self.vehicles[name] = VehicleMetrics(name, kind, self.world)

    def _pair_sink(self, pm: PairMetrics, a: str, b: str) -> Callable[[np.ndarray, np.ndarray], None]:
        on_pair = self.on_pair
        if on_pair is None:
            return pm.add

        def both(t: np.ndarray, rel_ned: np.ndarray) -> None:
            pm.add(t, rel_ned)
            on_pair(a, b, t, rel_ned)

        return both

    def add(self, chunk: VehicleTrace) -> None:
        """A chunk of one registered vehicle's trace."""
        self.vehicles[chunk.name].add(chunk)
        for (a, b), (_, matcher) in self.pairs.items():
            if chunk.name in (a, b):
                matcher.add(0 if chunk.name == a else 1, chunk.t, chunk.pos_ned)

    def result(self) -> dict:
        """The metrics so far, as plain JSON-able values."""
        return {
            "vehicles": {n: v.result() for n, v in self.vehicles.items()},
            "separation": {f"{a}-{b}": pm.result() for (a, b), (pm, _) in self.pairs.items()},
        }


def run_metrics(traces: list[VehicleTrace], world: MetricsWorld = EMPTY_WORLD) -> dict:
    """Every metric of whole traces (a replay), cut into the chunks a live run folds in."""
    acc = RunMetrics(world)
    for tr in traces:
        acc.vehicle(tr.name, tr.kind)
    for tr in traces:
        for chunk in tr.chunks(CHUNK):
            acc.vehicles[tr.name].add(chunk)
    for a, b in itertools.combinations(traces, 2):
        common, ia, ib = common_times(a, b)
        acc.pairs[(a.name, b.name)][0].add(common, a.pos_ned[ia] - b.pos_ned[ib])
    return acc.result()


def flatten(metrics: dict, prefix: str = "") -> dict[str, float | int | bool | None]:
    """Nested metrics as ``a.b.c`` keys (for tables and A/B comparison)."""
    flat: dict = {}
    for k, v in metrics.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            flat.update(flatten(v, key + "."))
        else:
            flat[key] = v
    return flat


def differing_keys(a: dict, b: dict) -> list[str]:
    """Keys where two metric sets differ (NaN equals NaN)."""
    fa, fb = flatten(a), flatten(b)
    diff = []
    for k in sorted(set(fa) | set(fb)):
        x, y = fa.get(k), fb.get(k)
        both_nan = isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y)
        if x != y and not both_nan:
            diff.append(k)
    return diff
