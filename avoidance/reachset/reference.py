"""Reference trajectory generator (spec §2.6, (6.49)): the timed positions of the movement
currently executing followed by the planned buffer, for the path tracker / MPTP.

Frame: z-up GCF [m], times [s]. The executing movement starts from the current state; the planned
buffer starts at the predicted state *levelled* (roll = pitch = 0, same heading), because the
reach set was computed and assessed for a level grid (A-12): the reference is exactly the
trajectory the avoidance grid run checked.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from avoidance.reachset.movement import KinState, MovementAutomaton


@dataclass(frozen=True, slots=True)
class ReferenceTrajectory:
    """(x_ref, y_ref, z_ref, t_ref) of (6.49): ``positions`` (K, 3) GCF [m], ``times`` (K,) [s];
    ``movement_end`` (K,) true at the end of a movement (false at intra-movement samples)."""

    positions: np.ndarray
    times: np.ndarray
    movement_end: np.ndarray


def level(s: KinState) -> KinState:
    return KinState(s.pos, np.array([0.0, 0.0, s.att[2]]), s.t, s.v)


def reference_trajectory(
    ma: MovementAutomaton, s_now: KinState, executing: int | None, planned: Sequence[int], sampled: bool = False
) -> ReferenceTrajectory:
    """Reference of ``executing`` (None: none, the plan starts now) then ``planned``."""
    parts, ends = [], []
    s = s_now
    if executing is not None:
        traj = ma.trajectory(s_now, [executing], sampled)
        parts.append(traj)
        s = ma.apply(s_now, executing)
    plan = ma.trajectory(level(s), planned, sampled)
    parts.append(plan[1:] if parts else plan)
    traj = np.concatenate(parts)
    n_sub = ma.table.config.n_sub if sampled else 1
    ends = (np.arange(len(traj)) % n_sub) == 0
    return ReferenceTrajectory(traj[:, :3], traj[:, 6], ends)
