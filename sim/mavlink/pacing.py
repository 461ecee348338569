"""Pacing sim time to the wall clock (for streaming to a GCS "paced to wall clock").

Sim-time mode needs no pacer: the caller simply publishes as fast as the simulation runs.
"""

from __future__ import annotations

import time
from collections.abc import Callable


class WallClockPacer:
    """Sleeps in :meth:`pace` so that sim time advances at most ``speed`` times as fast as wall
    time (``speed`` = 1: real time; 10: ten times faster).

    The first call anchors sim time to the wall clock. A simulation running slower than the pace
    is never sped up to catch up by more than ``max_lag_s`` of wall time: beyond that lag the
    anchor moves, so a slow stretch is not followed by a burst. A jump back in sim time
    re-anchors too (e.g. a replay restarted)."""

    def __init__(
        self,
        speed: float = 1.0,
        max_lag_s: float = 0.25,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ):
        if not speed > 0.0:
            raise ValueError(f"pacing speed must be > 0, got {speed}")
        self.speed = float(speed)
        self.max_lag_s = max_lag_s
        self._clock = clock
        self._sleep = sleep
        self._anchor: tuple[float, float] | None = None  # (sim time [s], wall time [s])
        self._last_t = -float("inf")

    def pace(self, t: float) -> float:
        """Wait until sim time ``t`` [s] is due; returns the time slept [s]."""
        now = self._clock()
        if self._anchor is None or t < self._last_t:
            self._anchor = (t, now)
        self._last_t = t
        t0, wall0 = self._anchor
        due = wall0 + (t - t0) / self.speed
        wait = due - now
        if wait > 0.0:
            self._sleep(wait)
            return wait
        if -wait > self.max_lag_s:
            self._anchor = (t, now)
        return 0.0
