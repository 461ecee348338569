"""World-level broad phase: which traffic can matter to which vehicle's planner.

Every vehicle and traffic object is a body at its true position [m] (local-level NED) with a
speed bound [m/s] (a vehicle: the larger of its speed and its mission's cruise speed; an object:
its constant speed) and a radius [m]. A vehicle whose planner declares an awareness ``(range R
[m], horizon H [s])`` (e.g. ``ReachSetAvoider.awareness``) is handed body j only if j can come
within R of it within H plus ``settle_s`` (the time its track needs to settle before it can be
rated), both moving at their speed bounds:

    |p_i - p_j| <= R + (s_i + s_j) (H + settle_s) + r_j.

Vehicles without an awareness get every body. The candidates come from a k-d tree over all
positions (one ball query per aware vehicle with the largest radius any body could need), then
the exact test above, so the world's cost grows with the number of bodies near each vehicle,
not with the square of the fleet.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

SETTLE_S = 10.0  # [s] reports a track gets before it can matter (tracker settling)


def relevant(
    pos: np.ndarray,
    speed: np.ndarray,
    radius: np.ndarray,
    awareness: list[tuple[float, float] | None],
    settle_s: float = SETTLE_S,
) -> list[np.ndarray]:
    """For each of the first ``len(awareness)`` bodies (the vehicles), the indices of the other
    bodies (vehicles and objects: rows of ``pos`` (N, 3), ``speed`` (N,), ``radius`` (N,)) that
    can matter to it, ascending."""
    pos, speed, radius = np.asarray(pos, float), np.asarray(speed, float), np.asarray(radius, float)
    n = len(pos)
    if pos.shape != (n, 3) or speed.shape != (n,) or radius.shape != (n,) or len(awareness) > n:
        raise ValueError("broad phase: pos must be (N, 3), speed and radius (N,), at most N vehicles")
    everyone = np.arange(n)
    declared = [(i, a) for i, a in enumerate(awareness) if a is not None]
    out = [everyone[everyone != i] for i in range(len(awareness))]
    if not declared:
        return out
    aware = [i for i, _ in declared]
    reach = np.array([a[0] for _, a in declared])
    look = np.array([a[1] for _, a in declared]) + settle_s
    query = reach + speed[aware] * look + (speed.max() * look + radius.max())
    tree = cKDTree(pos)
    for k, (i, cand) in enumerate(zip(aware, tree.query_ball_point(pos[aware], query), strict=True)):
        j = np.array(sorted(c for c in cand if c != i), dtype=np.int64)
        gap = np.linalg.norm(pos[j] - pos[i], axis=1)
        out[i] = j[gap <= reach[k] + (speed[i] + speed[j]) * look[k] + radius[j]]
    return out
