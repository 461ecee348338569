"""A run log folded into the run metrics message by message, as a live run folds them in.

Each vehicle's per-tick topics (truth state, setpoint, commands, estimate, 3-sigma bounds, true
tracking) are paired tick by tick in log order and handed to a :class:`TraceRecorder`, which
passes chunks of ``CHUNK`` log ticks to :class:`RunMetrics` and forgets them: the live path,
fed from the file. Planner latencies, cache hits, mission status and ``/log`` waypoint events
go to the same recorder. Memory holds one chunk per vehicle, whatever the log's length; ticks
missing a topic at the end of an unfinished log are dropped. Times: sim [s].
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from sim.mcap_read import LogInfo, LogReadError, iter_messages
from sim.replay.metrics import MetricsWorld, PairFn, RunMetrics
from sim.replay.trace import TraceRecorder, VehicleTrace

PER_TICK = ("truth/state", "ctrl/setpoint", "ctrl/commands", "est/state", "truth/tracking")
SIGMA = "est/sigma3"  # per tick too, for an estimator that gives bounds
PER_CALL = ("plan/latency", "plan/input", "mission/status")

ChunkFn = Callable[[VehicleTrace], None]


def log_vehicles(info: LogInfo) -> list[str]:
    """Names of the vehicles that logged a truth state, sorted."""
    return sorted(ti.topic.split("/")[1] for ti in info.topics if ti.topic.endswith("/truth/state"))


class _VehicleFeed:
    """One vehicle's logged messages into its recorder, a tick once every per-tick topic has it."""

    def __init__(self, recorder: TraceRecorder, sigma: bool):
        self.recorder = recorder
        self.queues: dict[str, deque[dict]] = {s: deque() for s in (*PER_TICK, *((SIGMA,) if sigma else ()))}

    def add(self, suffix: str, msg: dict) -> None:
        rec = self.recorder
        if suffix in self.queues:
            self.queues[suffix].append(msg)
            if all(self.queues.values()):
                self._tick()
        elif suffix == "plan/latency":
            rec.latency(float(msg["seconds"]))
        elif suffix == "plan/input":
            if not msg["new_plan"]:
                rec.cache_hit()
        elif suffix == "mission/status":
            rec.waypoints_total = int(msg["waypoints"])

    def event(self, t: float, text: str) -> None:
        """A ``/log`` event at sim time ``t`` [s]."""
        name = self.recorder.name
        if text.startswith(f"{name}: waypoint ") and text.endswith(" reached"):
            self.recorder.reached(t)
        elif text == f"{name}: mission complete":
            self.recorder.complete(t)

    def _tick(self) -> None:
        q = {s: d.popleft() for s, d in self.queues.items()}
        self.recorder.state(
            SimpleNamespace(**q["truth/state"]),  # type: ignore[arg-type]  # the fields a VehicleState has
            q["ctrl/setpoint"],
            q["ctrl/commands"]["properties"],
            float(q["truth/tracking"]["cross_track_m"]),
        )
        self.recorder.estimate(SimpleNamespace(**q["est/state"]), q.get(SIGMA))  # type: ignore[arg-type]


def stream_metrics(
    path: str | Path,
    info: LogInfo,
    world: MetricsWorld,
    on_chunk: ChunkFn | None = None,
    on_pair: PairFn | None = None,
    extra: tuple[str, ...] = (),
    on_message: Callable[[str, float, Any], None] | None = None,
) -> dict:
    """The run's metrics read from the log at ``path`` (its summary ``info``) in one pass;
    ``on_chunk`` sees every chunk a vehicle hands over, ``on_pair`` every pair's matched
    samples, ``on_message`` every message read (topic, sim time [s], decoded): the metrics'
    topics, ``/log`` and the ``extra`` topics."""
    acc = RunMetrics(world, on_pair)
    kinds = info.metadata.get("vehicles", {})
    topics = {ti.topic for ti in info.topics}
    wanted = {"/log", *extra}
    feeds: dict[str, _VehicleFeed] = {}

    def sink(chunk: VehicleTrace) -> None:
        acc.add(chunk)
        if on_chunk is not None:
            on_chunk(chunk)

    for name in log_vehicles(info):
        missing = [f"/{name}/{s}" for s in PER_TICK if f"/{name}/{s}" not in topics]
        if missing:
            raise LogReadError(f"{path}: no topic {', '.join(map(repr, missing))} (not a cosim run log, or edited)")
        kind = kinds.get(name, "fixed_wing")
        acc.vehicle(name, kind)
        feeds[name] = _VehicleFeed(TraceRecorder(name, kind, 0, sink), f"/{name}/{SIGMA}" in topics)
        wanted |= {f"/{name}/{s}" for s in (*PER_TICK, SIGMA, *PER_CALL)}
    for topic, t, msg in iter_messages(path, sorted(wanted & topics)):
        if on_message is not None:
            on_message(topic, t, msg)
        if topic == "/log":
            for feed in feeds.values():
                feed.event(t, msg.message)
            continue
        _, name, suffix = topic.split("/", 2) if topic.count("/") >= 2 else ("", "", "")
        if name in feeds:
            feeds[name].add(suffix, msg)
    for feed in feeds.values():
        feed.recorder.flush()
    return acc.result()
