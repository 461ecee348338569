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
    hold_s: dict[int, float] = field(default_factory=dict)  # hover time at waypoint index [s]
    land: bool = False  # a multirotor lands after the last waypoint
    landed_t: float | None = None  # sim time of touchdown [s]
    completed_t: float | None = None  # sim time the mission completed [s]

    @property
    def next_index(self) -> int:
        """Index of the waypoint being flown to (== len(waypoints) when complete)."""
        return len(self.reached)

    @property
    def waypoints_done(self) -> bool:
        return self.next_index >= len(self.waypoints)

    @property
    def complete(self) -> bool:
        return self.completed_t is not None

    def check_complete(self, t: float) -> bool:
        """Mark the mission complete at ``t`` once every waypoint is reached, the last one's hold
        is over and (landing mission) the vehicle has landed; True when it just completed."""
        if self.completed_t is not None or not self.waypoints_done:
            return False
        last, t_last = self.reached[-1]
        if t < t_last + self.hold_s.get(last, 0.0) or (self.land and self.landed_t is None):
            return False
        self.completed_t = t
        return True

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
