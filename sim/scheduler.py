"""Lockstep multi-rate scheduler.

Time advances in integer ticks of a base rate [Hz]. Every component has an integer divisor: a
plant integrates one step every ``divisor`` ticks, a task fires at ticks divisible by its
divisor. Plants are advanced in bulk between the ticks at which some task fires, so the Python
loop runs at the task rates, not the integration rate. Tasks at one tick fire in stage order
(environment -> sense -> estimate -> plan -> control -> log), then in registration order. Everything is integer
arithmetic: two runs interleave identically. The pattern of due tasks repeats with the least
common multiple of the divisors (the cycle), so it is worked out once per cycle phase: the loop
pays per tick only for the tasks and plant steps that are due.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import IntEnum
from math import lcm

_MAX_CYCLE = 1 << 20  # ticks; a longer cycle is not tabulated (the per-tick test is used)


class Stage(IntEnum):
    ENVIRONMENT = 0
    SENSE = 1
    ESTIMATE = 2
    PLAN = 3
    CONTROL = 4
    LOG = 5


@dataclass(slots=True)
class _Plant:
    name: str
    divisor: int
    step: Callable[[int], None]


@dataclass(slots=True)
class _Task:
    name: str
    divisor: int
    stage: Stage
    order: int
    fn: Callable[[float], None]
    plant: str | None  # the only plant it reads or writes (None: any plant)


@dataclass(frozen=True, slots=True)
class _Phase:
    """One event phase of the cycle: the tasks due, the gap to the next event [ticks] and each
    plant's steps over that gap (plant step function, step count > 0)."""

    due: tuple[Callable[[float], None], ...]
    gap: int
    steps: tuple[tuple[Callable[[int], None], int], ...]


class SchedulerError(ValueError):
    pass


class LockstepScheduler:
    def __init__(self, base_hz: int):
        if int(base_hz) != base_hz or base_hz <= 0:
            raise SchedulerError(f"base rate must be a positive integer [Hz], got {base_hz}")
        self.base_hz = int(base_hz)
        self.tick = 0
        self._plants: list[_Plant] = []
        self._tasks: list[_Task] = []
        self._cycle: tuple[int, dict[int, _Phase]] | None = None  # (length, event phase -> _Phase)

    @property
    def time(self) -> float:
        """Sim time of the current tick [s]."""
        return self.tick / self.base_hz

    def divisor_for(self, rate_hz: float, what: str) -> int:
        """The integer divisor giving ``rate_hz``; SchedulerError if it does not divide the base."""
        d = self.base_hz / rate_hz
        if rate_hz <= 0 or abs(d - round(d)) > 1e-9:
            raise SchedulerError(f"{what}: {rate_hz:g} Hz does not divide the base rate {self.base_hz} Hz")
        return round(d)

    def add_plant(self, name: str, rate_hz: float, step: Callable[[int], None]) -> None:
        """A plant integrated at ``rate_hz``; ``step(n)`` advances it n steps."""
        d = self.divisor_for(rate_hz, name)
        for t in self._tasks:
            if t.plant in (None, name):
                self._check(t.name, t.divisor, d)
        self._plants.append(_Plant(name, d, step))
        self._cycle = None

    def add_task(
        self, name: str, rate_hz: float, stage: Stage, fn: Callable[[float], None], plant: str | None = None
    ) -> None:
        """``fn(t)`` called at ``rate_hz``; the rate must be a sub-multiple of every plant rate
        (of ``plant``'s only, for a task that touches no other plant), so that tasks always see
        plants at exactly the tick time."""
        d = self.divisor_for(rate_hz, name)
        for p in self._plants:
            if plant in (None, p.name):
                self._check(name, d, p.divisor)
        self._tasks.append(_Task(name, d, stage, len(self._tasks), fn, plant))
        self._tasks.sort(key=lambda t: (t.stage, t.order))
        self._cycle = None

    def _check(self, task: str, task_div: int, plant_div: int) -> None:
        if task_div % plant_div:
            raise SchedulerError(
                f"{task}: its rate {self.base_hz / task_div:g} Hz is not a sub-multiple of a "
                f"plant rate {self.base_hz / plant_div:g} Hz"
            )

    def _next_event(self, limit: int) -> int:
        k = self.tick
        return min([limit] + [(k // t.divisor + 1) * t.divisor for t in self._tasks])

    def _tabulate(self) -> tuple[int, dict[int, _Phase]] | None:
        """The cycle's event phases (ticks mod the cycle length at which a task fires), or None
        when there are no tasks or the cycle is longer than ``_MAX_CYCLE``."""
        if not self._tasks:
            return None
        n = lcm(*[t.divisor for t in self._tasks], *[p.divisor for p in self._plants])
        if n > _MAX_CYCLE:
            return None
        events = sorted({k for t in self._tasks for k in range(0, n, t.divisor)})
        phases: dict[int, _Phase] = {}
        for k, nxt in zip(events, [*events[1:], n], strict=True):
            steps = tuple((p.step, nxt // p.divisor - k // p.divisor) for p in self._plants)
            phases[k] = _Phase(
                tuple(t.fn for t in self._tasks if k % t.divisor == 0), nxt - k, tuple(s for s in steps if s[1])
            )
        return n, phases

    def run(self, until_tick: int, stop: Callable[[], bool] = lambda: False) -> None:
        """Fire the tasks due now, then advance; ends after firing the tasks at ``until_tick``
        or when ``stop()`` turns true after a tick's tasks."""
        if self._cycle is None:
            self._cycle = self._tabulate()
        n, phases = self._cycle if self._cycle is not None else (1, {})
        while True:
            k = self.tick
            t = k / self.base_hz
            ph = phases.get(k % n)
            for fn in ph.due if ph is not None else [x.fn for x in self._tasks if k % x.divisor == 0]:
                fn(t)
            if k >= until_tick or stop():
                return
            if ph is not None and k + ph.gap <= until_tick:
                for step, count in ph.steps:
                    step(count)
                self.tick = k + ph.gap
                continue
            nxt = self._next_event(until_tick)  # no table, or the last, partial gap
            for p in self._plants:
                m = nxt // p.divisor - k // p.divisor
                if m:
                    p.step(m)
            self.tick = nxt
