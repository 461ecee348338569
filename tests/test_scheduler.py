"""Lockstep multi-rate scheduler: rates, ordering, bulk plant stepping."""

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from sim.scheduler import LockstepScheduler, SchedulerError, Stage


def test_tasks_fire_at_their_rates_and_plants_step_exactly():
    s = LockstepScheduler(240)
    steps = {"quad": 0, "haps": 0}
    calls: list[tuple[str, float, int, int]] = []
    s.add_plant("quad", 240, lambda n: steps.__setitem__("quad", steps["quad"] + n))
    s.add_plant("haps", 120, lambda n: steps.__setitem__("haps", steps["haps"] + n))
    s.add_task("log", 10, Stage.LOG, lambda t: calls.append(("log", t, steps["quad"], steps["haps"])))
    s.add_task("ctrl", 40, Stage.CONTROL, lambda t: calls.append(("ctrl", t, steps["quad"], steps["haps"])))
    s.add_task("plan", 1, Stage.PLAN, lambda t: calls.append(("plan", t, steps["quad"], steps["haps"])))
    s.run(240 * 2)
    assert steps == {"quad": 480, "haps": 240}
    assert sum(c[0] == "ctrl" for c in calls) == 81  # t = 0 .. 2 s inclusive at 40 Hz
    assert sum(c[0] == "log" for c in calls) == 21
    assert sum(c[0] == "plan" for c in calls) == 3
    # each call sees the plants exactly at its time
    for _name, t, q, h in calls:
        assert q == round(t * 240) and h == round(t * 120)
    # at a shared tick: plan before control before log, whatever the registration order
    at0 = [c[0] for c in calls if c[1] == 0.0]
    assert at0 == ["plan", "ctrl", "log"]


def test_rate_must_divide_base_and_plants():
    s = LockstepScheduler(120)
    s.add_plant("haps", 120, lambda n: None)
    with pytest.raises(SchedulerError, match="does not divide the base rate"):
        s.add_task("x", 7, Stage.LOG, lambda t: None)
    s2 = LockstepScheduler(240)
    s2.add_plant("haps", 120, lambda n: None)
    with pytest.raises(SchedulerError, match="not a sub-multiple of a plant rate"):
        s2.add_task("x", 240, Stage.LOG, lambda t: None)


def test_a_task_of_one_plant_runs_at_that_plants_rate_beside_a_slower_plant():
    s = LockstepScheduler(240)
    steps = {"quad": 0, "haps": 0}
    seen: list[tuple[float, int, int]] = []
    s.add_plant("quad", 240, lambda n: steps.__setitem__("quad", steps["quad"] + n))
    s.add_task("quad.sense", 240, Stage.SENSE, lambda t: seen.append((t, steps["quad"], steps["haps"])), plant="quad")
    s.add_plant("haps", 120, lambda n: steps.__setitem__("haps", steps["haps"] + n))  # the quad task is not its
    with pytest.raises(SchedulerError, match=r"haps\.sense: its rate 240 Hz is not a sub-multiple of a plant rate 120"):
        s.add_task("haps.sense", 240, Stage.SENSE, lambda t: None, plant="haps")
    s.run(240)
    assert steps == {"quad": 240, "haps": 120}
    assert len(seen) == 241
    assert all(q == round(t * 240) and h == int(t * 120 + 1e-9) for t, q, h in seen)


def test_stop_is_checked_after_each_tick():
    s = LockstepScheduler(100)
    seen = []
    s.add_task("t", 10, Stage.LOG, seen.append)
    s.run(10_000, stop=lambda: len(seen) >= 5)
    assert seen == [0.0, 0.1, 0.2, 0.3, 0.4]
    assert s.time == pytest.approx(0.4)


@given(base=st.sampled_from([60, 120, 240, 480]), div=st.integers(1, 48), n=st.integers(0, 2000))
def test_plant_steps_equal_ticks_over_divisor(base, div, n):
    s = LockstepScheduler(base)
    total = [0]
    s.add_plant("p", base / 1, lambda k: total.__setitem__(0, total[0] + k))
    if base % div == 0:
        s.add_task("t", base / div, Stage.LOG, lambda t: None)
    s.run(n)
    assert total[0] == n


@given(
    divisors=st.lists(st.sampled_from([1, 2, 3, 4, 6, 8, 12, 24, 48, 240]), min_size=1, max_size=6),
    plants=st.sets(st.sampled_from([1, 2, 3]), min_size=1),
    stops=st.lists(st.integers(0, 700), min_size=1, max_size=3),
)
def test_the_cycle_table_fires_and_steps_as_the_per_tick_test(divisors, plants, stops):
    """Tasks and plant steps, in order, with the cycle table and with the per-tick divisor test
    (a cycle longer than the table's limit), over runs that end between events."""

    def trace(max_cycle: int) -> list[tuple]:
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr("sim.scheduler._MAX_CYCLE", max_cycle)
            return flown()

    def flown() -> list[tuple]:
        s = LockstepScheduler(240)
        out: list[tuple] = []
        for d in sorted(plants):
            s.add_plant(f"p{d}", 240 / d, lambda n, d=d: out.append(("step", d, s.tick, n)))
        common = math.lcm(*plants)
        for i, d in enumerate(divisors):
            div = d * common
            s.add_task(f"t{i}", 240 / div, Stage(i % 6), lambda t, i=i: out.append(("task", i, t)))
        for until in sorted(stops):
            s.run(until)
        return out

    assert trace(1 << 20) == trace(0)
