"""D-23 (docs/reachset.md), finding 16 of docs/encounters.md: a multirotor herded by a parallel
intruder stops, lets it pass ahead and crosses behind it."""

from __future__ import annotations

import numpy as np
import pytest

from avoidance.reachset.gridrun import hover_clearance
from avoidance.reachset.mission import MissionControl
from avoidance.reachset.movement import KinState, multirotor_automaton
from avoidance.reachset.options import ReachSetOptions
from avoidance.reachset.planner import ReachSetAvoider
from sim.core.mission import Mission
from sim.core.plan import Threats
from sim.core.threats import IntruderTrack
from tests.test_reachset_mission_end import fly

CAMPAIGN = {"period": 1.0, "intruder_margin": 4.55, "intruder_margin_vertical": 2.0}  # reachset_quad_pairs


def fly_encounter(
    own: tuple[float, float, float, float], intruder: tuple[float, ...], stop_and_wait: bool, t_end: float
) -> tuple[float, np.ndarray]:
    """An encounter of reachset_quad_pairs from its truth state at 5 s, as a point mass with the
    campaign's options: ``own`` = (north, east, down [m], heading [deg]) at 5 m/s for the goal 75 m
    north of the origin at its height, ``intruder`` = (north, east, down [m], v_north, v_east
    [m/s]) flying straight, sensed exactly. Returns the completion time [s] (inf: not complete)
    and the (t, ownship NED, intruder NED) rows every 20 ms."""
    track = IntruderTrack("intruder", 0.0, np.array(intruder[:3]), np.array([*intruder[3:], 0.0]), 0.45)
    cfg = ReachSetOptions(**CAMPAIGN, stop_and_wait=stop_and_wait).avoidance_config()
    trace: list = []
    mission, _, _ = fly(
        [[75.0, 0.0, own[2]]],
        1.0,
        start=own[:3],
        heading_deg=own[3],
        speed=5.0,
        t_end=t_end,
        turns_in_place=True,
        cfg=cfg,
        intruder=track,
        trace=trace,
    )
    rows = np.array([[t, *p, *q] for t, p, q in trace])
    return (mission.completed_t if mission.complete else np.inf), rows


# encounter 118: the intruder on the left, course 50.5°, 4.46 m/s; 178: on the right, 342°, 4.45 m/s
DRAW_118 = ((-89.5, -0.3, -20.4, 0.0), (-41.2, -53.8, -20.4, 2.837, 3.441))
DRAW_178 = ((-99.2, -0.8, -20.6, -13.3), (-85.3, 29.2, -19.5, 4.227, -1.378))


def closest(rows: np.ndarray) -> float:
    return float(np.hypot(*(rows[:, 4:6] - rows[:, 1:3]).T).min())


def test_herded_multirotor_stops_and_crosses_behind_the_intruder():
    """Encounter 118: flying on, the ownship gives way to the right and then stays beside the
    intruder, which it outruns by only 0.54 m/s: every path towards the goal crosses ahead of the
    intruder or of its predicted right turn (complete at 61.9 s; the campaign's run ended
    incomplete at 77 s). While its give-way path still gains on the goal it is flown as before
    (the same track to 30 s); once the path gains nothing (35 s), the ownship stops, lets the
    intruder pass ahead and crosses behind it: complete at 54.1 s, > 5 m apart (6.97 m: the body
    and margin kept)."""
    t_with, with_stop = fly_encounter(*DRAW_118, True, 58.0)
    t_without, without = fly_encounter(*DRAW_118, False, 58.0)
    assert t_with < 58.0 <= t_without, (t_with, t_without)
    np.testing.assert_array_equal(with_stop[with_stop[:, 0] <= 30.0], without[without[:, 0] <= 30.0])
    assert closest(with_stop) > 5.0


def test_the_wait_lasts_until_the_intruder_has_passed():
    """Encounter 178: the intruder 20 m behind on the right, nearly parallel; no path from a stop
    one period later gets behind it, waiting several periods does: complete at 44.3 s, 15.5 m
    apart (waiting one period at most, or not at all: 70.5 s)."""
    t_with, with_stop = fly_encounter(*DRAW_178, True, 55.0)
    assert t_with < 55.0, t_with
    assert closest(with_stop) > 10.0


def stop_point(goal_enu: list[float]) -> np.ndarray | None:
    """One emergency decision (stop and wait on) at the GCF origin heading north at 5 m/s, 20 m
    up, an intruder 30 m north, 10 m west, flying east at 4 m/s: where the vehicle stops."""
    cfg = ReachSetOptions(**CAMPAIGN, stop_and_wait=True).avoidance_config()
    mc = MissionControl(np.array([goal_enu]), multirotor_automaton(5.0, 1.0), cfg, advance_on_reach=False)
    track = IntruderTrack("i", 0.0, np.array([30.0, -10.0, -20.0]), np.array([0.0, 4.0, 0.0]), 0.45)
    d = mc.step(KinState(np.array([0.0, 0.0, 20.0]), np.array([0.0, 0.0, np.pi / 2]), 0.0, 5.0), Threats([track]))
    assert d.mode.value == "emergency" and d.status == "ok"
    assert ("stop" in d.events) == (mc.stop_point is not None) and (mc.stop_point is None) == bool(d.buffer)
    return mc.stop_point


def test_a_vehicle_whose_paths_gain_nothing_stops_by_hand():
    """Goal 200 m behind: every path of the ±45° grid ends farther from it than the grid origin
    (5 m ahead), while the grid there facing the goal holds paths towards it (tip ~50 m nearer,
    more than the 5 m of one period's flight): the vehicle stops at the grid origin. Goal 200 m
    ahead: its paths gain, it flies on."""
    np.testing.assert_allclose(stop_point([0.0, -200.0, 20.0]), [0.0, 5.0, 20.0], atol=1e-9)
    assert stop_point([0.0, 200.0, 20.0]) is None


def test_hover_clearance_by_hand():
    """An intruder 12 m ahead, 3 m above, flying at the hovering vehicle at 5 m/s, body 5 m,
    vertical margin 2 m: after 1 s it is 7 m ahead and 3 - 2 = 1 m above the capsule's reach,
    sqrt(49 + 1) - 5 = 2.07 m clear; 3 s of hover reach it (negative). Its right turn keeps it
    farther than the straight line here; no intruder: +inf."""
    row = np.array([[12.0, 0.0, 3.0, -5.0, 0.0, 0.0, 5.0]])
    assert hover_clearance(row, 1.0, 0.0, 2.0) == pytest.approx(np.sqrt(50.0) - 5.0)
    assert hover_clearance(row, 3.0, 0.0, 2.0) < 0.0
    assert hover_clearance(row, 1.0, np.radians(15.0), 2.0) == pytest.approx(np.sqrt(50.0) - 5.0)
    assert hover_clearance(np.zeros((0, 7)), 1.0, 0.0) == np.inf


def test_stop_and_wait_is_an_option_of_vehicles_that_turn_in_place():
    cfg = ReachSetOptions(**CAMPAIGN, stop_and_wait=True).avoidance_config()
    assert cfg.mission.stop_and_wait
    assert not ReachSetOptions(**CAMPAIGN).avoidance_config().mission.stop_and_wait
    mission = Mission(np.array([[100.0, 0.0, -20.0]]), cruise_speed=5.0, acceptance_radius=1.0)
    ReachSetAvoider(mission, multirotor_automaton(5.0, 1.0), cfg, turns_in_place=True)
    with pytest.raises(ValueError, match="stop_and_wait"):
        ReachSetAvoider(mission, multirotor_automaton(5.0, 1.0), cfg, turns_in_place=False)


def test_a_stopped_vehicle_does_not_hover_on_where_an_intruder_will_reach_it():
    """Stopped as in the by-hand test (goal 200 m behind), then, one period later, a second
    intruder 12 m beyond the hover point flies at it at 6 m/s: the hover is not clear for two
    periods, so the vehicle leaves it (no stop point) although no path keeps every margin
    either: a stopped vehicle with no such path stays only where the hover is clear."""
    cfg = ReachSetOptions(**CAMPAIGN, stop_and_wait=True).avoidance_config()
    mc = MissionControl(np.array([[0.0, -200.0, 20.0]]), multirotor_automaton(5.0, 1.0), cfg, advance_on_reach=False)
    first = IntruderTrack("i", 0.0, np.array([30.0, -10.0, -20.0]), np.array([0.0, 4.0, 0.0]), 0.45)
    mc.step(KinState(np.array([0.0, 0.0, 20.0]), np.array([0.0, 0.0, np.pi / 2]), 0.0, 5.0), Threats([first]))
    hover = mc.stop_point
    assert hover is not None
    moved = IntruderTrack("i", 1.0, np.array([30.0, -6.0, -20.0]), np.array([0.0, 4.0, 0.0]), 0.45)
    at_it = IntruderTrack("j", 1.0, np.array([hover[1] + 12.0, hover[0], -hover[2]]), np.array([-6.0, 0.0, 0.0]), 0.45)
    d = mc.step(KinState(hover, np.array([0.0, 0.0, np.pi / 2]), 1.0, 5.0), Threats([moved, at_it]))
    assert d.mode.value == "emergency" and d.status != "ok"
    assert mc.stop_point is None and "stop" not in d.events
