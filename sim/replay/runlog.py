"""A run's MCAP log as arrays per topic.

``RunLog(path).topic("/haps/truth/state")`` gives a :class:`Series`: sim times ``t`` (N,) [s] and
one numpy array per numeric field (vectors as (N, k) arrays), built once and cached. Messages
are dicts, JSON or protobuf alike (:mod:`sim.mcap_read`); Foxglove types are kept as objects in
``Series.messages``. A compact log's LiDAR scans (``/<v>/threats/lidar``) are also put back into
their ``/<v>/threats`` messages as ``lidar``, as JSON logs carry them. ``RunLog(path).frame(topic)``
gives the topic as a pandas DataFrame.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from sim.mcap_read import LogInfo, LogReadError, iter_messages, read_info
from sim.replay.frame import frame

if TYPE_CHECKING:
    import pandas as pd

SCAN_SUFFIX = "/threats/lidar"  # a compact log's LiDAR scans, merged into /<v>/threats


@dataclass
class Series:
    """Messages of one topic: times [s], numeric fields as arrays, the decoded messages."""

    topic: str
    t: np.ndarray
    messages: list[Any]
    _fields: dict[str, np.ndarray] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.t)

    def __getitem__(self, name: str) -> np.ndarray:
        """A field of JSON messages as an array ((N,) or (N, k)); nested keys with dots."""
        arr = self._fields.get(name)
        if arr is None:
            values = [_get(m, name) for m in self.messages]
            try:
                arr = np.asarray(values, dtype=float)
            except (TypeError, ValueError):
                arr = np.asarray(values, dtype=object)
            self._fields[name] = arr
        return arr


def _get(message: Any, dotted: str):
    node = message
    for key in dotted.split("."):
        node = node[key] if isinstance(node, dict) else getattr(node, key)
    return node


class RunLog:
    """A run read into memory in one pass over the file: every topic, or only ``topics``."""

    def __init__(self, path: str | Path, topics: list[str] | None = None):
        self.path = Path(path)
        self.info: LogInfo = read_info(self.path)
        by_topic: dict[str, tuple[list[float], list[Any]]] = defaultdict(lambda: ([], []))
        for topic, t, msg in iter_messages(self.path, topics):
            ts, ms = by_topic[topic]
            ts.append(t)
            ms.append(msg)
        self._series = {k: Series(k, np.asarray(ts), ms) for k, (ts, ms) in by_topic.items()}
        for topic in by_topic:
            if topic.endswith(SCAN_SUFFIX) and topic[: -len(SCAN_SUFFIX)] + "/threats" in by_topic:
                self._merge_scans(topic[: -len(SCAN_SUFFIX)] + "/threats", topic)

    def _merge_scans(self, threats: str, scans: str) -> None:
        """Put each LiDAR scan of a compact log back into its threats message (same log time) as
        ``lidar``, as a JSON log carries it."""
        s = self._series[scans]
        at = dict(zip(s.t.tolist(), s.messages, strict=True))
        th = self._series[threats]
        for t, msg in zip(th.t.tolist(), th.messages, strict=True):
            if "lidar" not in msg:
                scan = at.get(t)
                if scan is None:
                    raise LogReadError(f"{self.path}: {threats} at {t} s has no scan on {scans}")
                msg["lidar"] = scan

    @property
    def topics(self) -> list[str]:
        return sorted(self._series)

    def has(self, topic: str) -> bool:
        return topic in self._series

    def topic(self, name: str) -> Series:
        try:
            return self._series[name]
        except KeyError:
            raise LogReadError(f"{self.path}: no topic {name!r} (has: {', '.join(self.topics)})") from None

    def frame(self, name: str) -> pd.DataFrame:
        """The topic as a pandas DataFrame: one row per message, nested fields as dotted
        columns, indexed by sim time [s] (:mod:`sim.replay.frame`)."""
        s = self.topic(name)
        return frame(s.t, s.messages)

    @cached_property
    def vehicles(self) -> list[str]:
        """Names of the vehicles that logged a truth state."""
        return sorted(t.split("/")[1] for t in self._series if t.endswith("/truth/state"))

    @property
    def metadata(self) -> dict[str, dict[str, str]]:
        return self.info.metadata

    def events(self) -> list[tuple[float, str]]:
        """(sim time, text) of every ``/log`` event."""
        if not self.has("/log"):
            return []
        s = self.topic("/log")
        return [(float(t), m.message) for t, m in zip(s.t, s.messages, strict=False)]
