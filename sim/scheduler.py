"""Lockstep multi-rate scheduler.

Time advances in integer ticks of a base rate [Hz]. Every component has an integer divisor: a
plant integrates one step every ``divisor`` ticks, a task fires at ticks divisible by its
divisor. Plants are advanced in bulk between the ticks at which some task fires, so the Python
loop runs at the task rates, not the integration rate. Tasks at one tick fire in stage order
(environment -> sense -> estimate -> plan -> control -> log), then in registration order. Everything is integer
arithmetic: two runs interleave identically.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import IntEnum


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

    def _check(self, task: str, task_div: int, plant_div: int) -> None:
        if task_div % plant_div:
            raise SchedulerError(
                f"{task}: its rate {self.base_hz / task_div:g} Hz is not a sub-multiple of a "
                f"plant rate {self.base_hz / plant_div:g} Hz"
            )

    def _next_event(self, limit: int) -> int:
        k = self.tick
        return min([limit] + [(k // t.divisor + 1) * t.divisor for t in self._tasks])

    def run(self, until_tick: int, stop: Callable[[], bool] = lambda: False) -> None:
        """Fire the tasks due now, then advance; ends after firing the tasks at ``until_tick``
        or when ``stop()`` turns true after a tick's tasks."""
        while True:
            k = self.tick
            t = k / self.base_hz
            for task in self._tasks:
                if k % task.divisor == 0:
                    task.fn(t)
            if k >= until_tick or stop():
                return
            nxt = self._next_event(until_tick)
            for p in self._plants:
                n = nxt // p.divisor - k // p.divisor
                if n:
                    p.step(n)
            self.tick = nxt
