"""D-23 (docs/reachset.md), finding 16 of docs/encounters.md: a multirotor herded by a parallel
intruder stops, lets it pass ahead and crosses behind it."""

from __future__ import annotations

import numpy as np
import pytest

from avoidance.reachset.gridrun import hover_clearance
from avoidance.reachset.movement import multirotor_automaton
from avoidance.reachset.options import ReachSetOptions
from avoidance.reachset.planner import ReachSetAvoider
from sim.core.mission import Mission
from sim.core.threats import IntruderTrack
from tests.test_reachset_mission_end import fly

CAMPAIGN = {"period": 1.0, "intruder_margin": 4.55, "intruder_margin_vertical": 2.0}  # reachset_quad_pairs


def fly_draw_118(stop_and_wait: bool, t_end: float) -> tuple[bool, float, float]:
    """Encounter 118 of reachset_quad_pairs from its truth state at 5 s (NED [m], m/s): the ownship
    at (-89.5, -0.3) heading north at 5 m/s for its goal 75 m north of the origin, the intruder at
    (-41.2, -53.8) on course 50.5° at 4.46 m/s (on the left, converging, sensed exactly); the
    campaign's options, point mass. Returns (complete, completion time [s], smallest horizontal
    distance [m])."""
    intruder = IntruderTrack("intruder", 0.0, np.array([-41.2, -53.8, -20.4]), np.array([2.837, 3.441, 0.0]), 0.45)
    cfg = ReachSetOptions(**CAMPAIGN, stop_and_wait=stop_and_wait).avoidance_config()
    trace: list = []
    mission, _, _ = fly(
        [[75.0, 0.0, -20.4]],
        1.0,
        start=(-89.5, -0.3, -20.4),
        speed=5.0,
        t_end=t_end,
        turns_in_place=True,
        cfg=cfg,
        intruder=intruder,
        trace=trace,
    )
    rel = np.array([q - p for _, p, q in trace])
    done = mission.completed_t if mission.complete else float("inf")
    return mission.complete, done, float(np.hypot(rel[:, 0], rel[:, 1]).min())


def test_herded_multirotor_stops_and_crosses_behind_the_intruder():
    """Flying on, every path towards the goal crosses ahead of the intruder (or its predicted
    right turn): the ownship gives way to the right and then stays beside the intruder, which it
    outruns by only 0.54 m/s (complete at 61.9 s; the campaign's run ended incomplete at 77 s).
    Stopping lets the intruder pass ahead and the ownship crosses behind it: complete at 34.0 s,
    13.6 m apart at the closest."""
    complete, t_done, closest = fly_draw_118(True, 45.0)
    assert complete and t_done < 40.0, t_done
    assert closest > 12.0, closest
    complete, _, _ = fly_draw_118(False, 45.0)
    assert not complete


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
