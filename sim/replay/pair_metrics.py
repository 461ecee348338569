"""Metrics of a pair of vehicles at their common log times, folded in as their chunks come.

Positions NED [m], times sim [s].
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from sim.replay.metrics_world import EMPTY_WORLD, MetricsWorld
from sim.replay.reducers import CylinderSeparation, Intervals, RunningMin
from sim.replay.trace import VehicleTrace


def common_times(a: VehicleTrace, b: VehicleTrace) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Log times [s] two vehicles share and their indices in each. Matched to the microsecond:
    a state's time is its plant's accumulated step, so a 120 Hz and a 240 Hz plant log the same
    tick as e.g. 0.1 and 0.09999999999999999."""
    _, ia, ib = np.intersect1d(_microseconds(a.t), _microseconds(b.t), assume_unique=True, return_indices=True)
    return a.t[ia], ia, ib


def _microseconds(t: np.ndarray) -> np.ndarray:
    return np.round(t * 1e6).astype(np.int64)


class PairMetrics:
    """Two vehicles at their common log times: the smallest 3-D distance [m] and when,
    :class:`CylinderSeparation` of the pair, and the intervals inside each other's well-clear
    volume (start, end [s], smallest distance [m])."""

    def __init__(self, world: MetricsWorld):
        self.world = world
        self.closest = RunningMin()
        self.cylinder = CylinderSeparation(world.nmac_h_m, world.nmac_v_m, world.well_clear_h_m, world.well_clear_v_m)
        self.losses = Intervals()

    def add(self, t: np.ndarray, rel_ned: np.ndarray) -> None:
        """Relative positions (N, 3) NED [m] at common times ``t`` [s], after the last ones."""
        if not t.size:
            return
        dist = np.linalg.norm(rel_ned, axis=1)
        self.closest.add(t, dist)
        self.cylinder.add(t, rel_ned)
        w = self.world
        inside = (np.hypot(rel_ned[:, 0], rel_ned[:, 1]) < w.well_clear_h_m) & (
            np.abs(rel_ned[:, 2]) < w.well_clear_v_m
        )
        self.losses.add(t, inside, dist)

    def result(self) -> dict:
        losses = self.losses.result()
        return {
            **self.closest.distance(),
            **self.cylinder.result(),
            "well_clear_losses": len(losses),
            "well_clear_loss_events": losses,
        }


class PairMatcher:
    """Pairs two vehicles' chunks at their common log times (to the microsecond) as they come;
    holds only the samples the other vehicle may still log a match for; ``out`` gets the
    matched (times [s], offsets a - b NED [m])."""

    def __init__(self, out: Callable[[np.ndarray, np.ndarray], None]):
        self.out = out
        self.pending: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = [_empty(), _empty()]  # (µs, t, pos)
        self.last_us = [np.iinfo(np.int64).min, np.iinfo(np.int64).min]

    def add(self, side: int, t: np.ndarray, pos: np.ndarray) -> None:
        if not t.size:
            return
        us = _microseconds(t)
        mine = tuple(np.concatenate([a, b]) for a, b in zip(self.pending[side], (us, t, pos), strict=True))
        other = self.pending[1 - side]
        _, i_mine, i_other = np.intersect1d(mine[0], other[0], assume_unique=True, return_indices=True)
        a, b = (mine, other) if side == 0 else (other, mine)
        ia, ib = (i_mine, i_other) if side == 0 else (i_other, i_mine)
        self.out(a[1][ia], a[2][ia] - b[2][ib])
        self.last_us[side] = int(us[-1])
        keep_mine = np.ones(len(mine[0]), bool)
        keep_mine[i_mine] = False
        keep_mine &= mine[0] > self.last_us[1 - side]
        keep_other = np.ones(len(other[0]), bool)
        keep_other[i_other] = False
        keep_other &= other[0] > self.last_us[side]
        self.pending[side] = tuple(x[keep_mine] for x in mine)  # type: ignore[assignment]
        self.pending[1 - side] = tuple(x[keep_other] for x in other)  # type: ignore[assignment]


def _empty() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return np.zeros(0, np.int64), np.zeros(0), np.zeros((0, 3))


def min_separation(a: VehicleTrace, b: VehicleTrace, world: MetricsWorld = EMPTY_WORLD) -> dict:
    """:class:`PairMetrics` of two whole traces, without the well-clear loss list."""
    pm = PairMetrics(world)
    common, ia, ib = common_times(a, b)
    pm.add(common, a.pos_ned[ia] - b.pos_ned[ib])
    out = pm.result()
    del out["well_clear_loss_events"]
    return out
