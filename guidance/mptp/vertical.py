"""Which storm cells a plan must avoid: the vertical filter of 3-D storm cells.

Heights are above the scenario origin, ``up = -D`` [m]; a cell is the prism of its polygon
between its base and top (``StormSnapshot.extents``).

Rule. The planner flies level in its own model, so it avoids a cell over the whole horizon or
not at all. Over the horizon the vehicle's height lies in the band from its current height
towards the goal's, as far as ``climb_rate_mps`` takes it in ``horizon_s`` (the band
[lo, hi]). A cell applies when that band comes within ``vertical_margin_m`` of its extent:
base - margin < hi and lo < top + margin. A climbing aircraft (lo = its current height)
therefore avoids a cell until it is ``vertical_margin_m`` above the cell's top, and from then on
plans straight over it; a cell whose base is more than the margin above everything the aircraft
can reach in the horizon is ignored too. Cells without a vertical extent always apply.

The same rule gives the heights of a plan that does not reach the goal (a partial search, a
holding orbit, straight flight in the safe area): from the current height towards the goal's at
``climb_rate_mps`` over the plan's time, never beyond the horizon's reach (``height_towards``),
so such a plan keeps climbing or descending inside the band its cells were chosen for.
"""

from __future__ import annotations

import numpy as np

from sim.core.threats import StormSnapshot


def height_towards(
    up_now_m: float, up_goal_m: float, climb_rate_mps: float, elapsed_s: float | np.ndarray
) -> np.ndarray:
    """Heights [m] after ``elapsed_s`` [s] (any shape) from ``up_now_m`` towards ``up_goal_m`` at
    ``climb_rate_mps`` [m/s], stopping at the goal's height."""
    reach = climb_rate_mps * np.asarray(elapsed_s, float)
    return up_now_m + np.clip(up_goal_m - up_now_m, -reach, reach)


def altitude_band(up_now_m: float, up_goal_m: float, climb_rate_mps: float, horizon_s: float) -> tuple[float, float]:
    """Heights [m] the vehicle may be at over the horizon: from ``up_now_m`` towards ``up_goal_m``
    at most ``climb_rate_mps`` [m/s] for ``horizon_s`` [s]."""
    end = float(height_towards(up_now_m, up_goal_m, climb_rate_mps, horizon_s))
    return min(up_now_m, end), max(up_now_m, end)


def applies(snapshot: StormSnapshot, band: tuple[float, float], margin_m: float) -> np.ndarray:
    """Which cells (bool (N,)) of ``snapshot`` come within ``margin_m`` [m] of the height band."""
    ext = snapshot.extents()
    return (ext[:, 0] - margin_m < band[1]) & (band[0] < ext[:, 1] + margin_m)


def cells_in_band(
    storms: list[StormSnapshot], band: tuple[float, float], margin_m: float
) -> tuple[list[StormSnapshot], tuple[tuple[int, ...], ...]]:
    """The snapshots with only the cells that apply (the same objects where every cell does),
    and the indices of the dropped cells per snapshot (a cache key)."""
    out, dropped = [], []
    for s in storms:
        keep = applies(s, band, margin_m)
        dropped.append(tuple(int(i) for i in np.flatnonzero(~keep)))
        if keep.all():
            out.append(s)
            continue
        vel = None if s.velocities_ne is None else np.asarray(s.velocities_ne, float)[keep]
        cells = tuple(c for c, k in zip(s.cells, keep, strict=True) if k)
        out.append(StormSnapshot(s.t, cells, vel, s.extents()[keep]))
    return out, tuple(dropped)
