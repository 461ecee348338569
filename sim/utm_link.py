"""The modelled C2/UTM link of one vehicle (spec §7.1): one-way latency, message loss and outage
windows, the same for both directions (position notifications and acknowledgements up,
directives down).

A message sent at ``t`` [s] arrives at ``t + latency`` unless it is lost: drawn with probability
``loss`` (one draw per message from the link's own stream, so the draws do not depend on the
outages), or sent or due during an outage. Delivery happens at the first UTM tick at or after
the arrival time (the authority's tick is the log rate). Sim seconds throughout.
"""

from __future__ import annotations

import heapq
import itertools
from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass(slots=True)
class Link:
    latency: float  # [s]
    loss: float  # probability in [0, 1)
    outages: tuple[tuple[float, float], ...]  # [start, end) windows [s]
    rng: np.random.Generator

    def up(self, t: float) -> bool:
        """Whether the link carries messages at ``t`` [s]."""
        return not any(a <= t < b for a, b in self.outages)

    def arrival(self, t: float) -> float | None:
        """Arrival time [s] of a message sent at ``t``, or None when it is lost."""
        dropped = bool(self.rng.random() < self.loss)
        due = t + self.latency
        return None if dropped or not (self.up(t) and self.up(due)) else due


@dataclass(slots=True)
class Queue:
    """Messages in flight, delivered in arrival order (ties in sending order)."""

    _heap: list[tuple[float, int, Any]] = field(default_factory=list)
    _seq: itertools.count = field(default_factory=itertools.count)

    def put(self, arrival: float, msg: Any) -> None:
        heapq.heappush(self._heap, (arrival, next(self._seq), msg))

    def due(self, t: float) -> list[Any]:
        """Every message that has arrived by ``t`` [s], oldest first."""
        out = []
        while self._heap and self._heap[0][0] <= t + 1e-9:
            out.append(heapq.heappop(self._heap)[2])
        return out
