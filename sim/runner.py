"""Run one scenario to one MCAP log.

The log is finished in a ``finally``: a run that raises, is interrupted (Ctrl-C, SIGTERM) or
diverges leaves a readable file with every message up to its last tick, and metadata ``result``
saying how it ended. Nothing wall-clock goes into the messages except the fields a channel lists
in its ``wallclock_fields`` metadata (with ``wallclock=true``), so the same scenario and seed give
the same message payloads otherwise.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import jsbsim

from sim import __version__
from sim.mcap_log import McapLog
from sim.replay.metrics import MetricsWorld, RunMetrics
from sim.scenario import Scenario
from sim.scheduler import LockstepScheduler, Stage
from sim.stop_requests import StopRequests
from sim.vehicle_log import write_static_frames
from sim.world import World


@dataclass
class MissionResult:
    reached: int
    waypoints: int
    complete: bool
    complete_time_s: float | None


@dataclass
class RunResult:
    scenario: str
    log_path: Path
    status: str  # "completed" | "duration_elapsed" | "crashed" | "interrupted" | "failed"
    sim_time_s: float
    wall_time_s: float
    missions: dict[str, MissionResult] = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)
    error: str | None = None

    @property
    def real_time_factor(self) -> float:
        return self.sim_time_s / self.wall_time_s if self.wall_time_s > 0 else math.inf


class RunFailed(RuntimeError):
    """The run raised; ``result`` says how far it got and where its log is."""

    def __init__(self, result: RunResult):
        super().__init__(
            f"{result.scenario}: run failed at t={result.sim_time_s:.2f} s: {result.error} (log: {result.log_path})"
        )
        self.result = result


ProgressFn = Callable[[float, float], None]  # (sim time, end time) [s]


def run_scenario(
    scenario: Scenario,
    out: str | Path,
    *,
    scenario_text: str = "",
    duration: float | None = None,
    progress: ProgressFn | None = None,
    progress_hz: float = 1.0,
    tick_hook: Callable[[float], None] | None = None,
) -> RunResult:
    """Fly ``scenario`` for ``duration`` [s] (default: the scenario's) and log it to ``out``.

    ``tick_hook(t)`` runs after each log tick (tests use it to inject failures).
    Returns a RunResult; raises RunFailed (log already closed) if the simulation raised.
    """
    end = float(duration if duration is not None else scenario.duration)
    if not (math.isfinite(end) and end > 0.0):
        raise ValueError(f"duration: must be a finite number of seconds > 0, got {end!r}")
    log = McapLog(out, scenario.epoch_ns, compact=scenario.logging.encoding == "protobuf")
    result = RunResult(scenario.name, Path(out), "failed", 0.0, 0.0)
    wall0 = time.perf_counter()
    sched: LockstepScheduler | None = None
    world: World | None = None
    metrics: RunMetrics | None = None
    failure: Exception | None = None
    session = None
    try:
        log.metadata(
            "run",
            {
                "scenario": scenario.name,
                "seed": scenario.seed,
                "epoch_ns": scenario.epoch_ns,
                "cosim_version": __version__,
                "jsbsim_version": jsbsim.__version__,
                "duration_s": end,
            },
        )
        if scenario_text:
            log.attach("scenario.toml", scenario_text.encode(), "application/toml")
        if scenario.weather is not None and scenario.weather.nowcast_files:  # where they were read
            log.metadata("weather", {"nowcast_files": json.dumps(scenario.weather.nowcast_files)})
        write_static_frames(log)
        world = World(scenario, log)
        metrics = RunMetrics(MetricsWorld.from_scenario(scenario, end))
        for v in world.vehicles:
            metrics.vehicle(v.name, v.recorder.kind)
            v.recorder.sink = metrics.add
        sched = LockstepScheduler(world.base_hz)
        world.schedule(sched)
        if scenario.mavlink.enabled:
            from sim.mavlink.session import MavlinkSession

            session = MavlinkSession(scenario.mavlink, world.vehicles, world.origin, log, world.fences)
            sched.add_task("mavlink", scenario.logging.rate_hz, Stage.LOG, session.tick)
        if progress is not None:
            sched.add_task("progress", progress_hz, Stage.LOG, lambda t: progress(t, end))
        if tick_hook is not None:
            sched.add_task("tick_hook", scenario.logging.rate_hz, Stage.LOG, tick_hook)
        log.event(0.0, f"run start: {scenario.name} (seed {scenario.seed})")
        swc = scenario.stop_when_complete
        required = swc if isinstance(swc, list) else None
        with StopRequests() as user:
            sched.run(
                round(end * world.base_hz),
                stop=lambda: user.requested or world.crashed() or (swc is not False and world.all_complete(required)),
            )
        if user.requested:
            raise KeyboardInterrupt
        if world.crashed():
            result.status = "crashed"
            result.error = "; ".join(f"{c.vehicle} {c.describe()}" for c in world.crashes)
        else:
            result.status = "completed" if world.all_complete(required) else "duration_elapsed"
    except KeyboardInterrupt:
        result.status = "interrupted"
        result.error = "interrupted by the user"
    except Exception as exc:  # noqa: BLE001 - recorded in the log, then re-raised as RunFailed
        result.status = "failed"
        result.error = f"{type(exc).__name__}: {exc}"
        failure = exc
    finally:
        if session is not None:
            session.close()
        result.sim_time_s = sched.time if sched is not None else 0.0
        result.wall_time_s = time.perf_counter() - wall0
        vehicles = world.vehicles if world is not None else []
        for v in vehicles:
            m = v.mission
            result.missions[v.name] = MissionResult(len(m.reached), len(m.waypoints), m.complete, m.completed_t)
        try:
            for v in vehicles:
                v.feed_metrics()
                v.recorder.flush()
            result.metrics = (metrics or RunMetrics()).result()
            log.metadata("metrics", {"json": json.dumps(result.metrics, sort_keys=True)})
            if result.status != "completed":
                log.event(
                    result.sim_time_s,
                    f"run ended: {result.status}" + (f" ({result.error})" if result.error else ""),
                    level="error" if result.status in ("failed", "crashed") else "warning",
                )
            log.metadata(
                "result",
                {
                    "status": result.status,
                    "sim_time_s": repr(result.sim_time_s),
                    **{f"{n}.mission_complete": str(r.complete) for n, r in result.missions.items()},
                    **({"error": result.error} if result.error else {}),
                },
            )
        finally:
            log.close()
    if failure is not None:
        raise RunFailed(result) from failure
    return result
