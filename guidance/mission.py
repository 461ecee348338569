"""Waypoint missions and their progress.

Waypoints are local-level NED positions [m] (D = -(altitude MSL - origin altitude)); the mission
is complete when its last waypoint has been reached. Progress is advanced by the plan follower,
which knows when a vertex labelled with a waypoint index has been passed.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(slots=True)
class Mission:
    """Ordered waypoints (N, 3) NED [m], cruise speed [m/s] and acceptance radius [m]."""

    waypoints: np.ndarray
    cruise_speed: float
    acceptance_radius: float
    reached: list[tuple[int, float]] = field(default_factory=list)  # (index, sim time [s])
    start: np.ndarray | None = None  # where the first leg starts (NED [m])

    @property
    def next_index(self) -> int:
        """Index of the waypoint being flown to (== len(waypoints) when complete)."""
        return len(self.reached)

    @property
    def complete(self) -> bool:
        return self.next_index >= len(self.waypoints)

    def mark_reached(self, index: int, t: float) -> bool:
        """Record waypoint ``index`` reached at ``t``; True if that was news."""
        if index != self.next_index:
            return False
        self.reached.append((index, t))
        return True

    def leg_start(self) -> np.ndarray:
        """Start of the current leg: the last waypoint reached, or the mission start."""
        if self.reached:
            return self.waypoints[self.reached[-1][0]]
        return self.start if self.start is not None else self.waypoints[0]
