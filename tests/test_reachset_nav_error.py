"""The reach-set avoider's allowance for the ownship's vertical navigation error
(``intruder_margin_vertical``, finding 11 of docs/encounters.md): encounter 60's ownship EKF put
it 3.6 m (2.6 sigma) below where it was, so an intruder truly 1.9 m below looked 1.9 m above; the
planner passed "under" it, kept its 5 m margin in its own picture (5.7 m) and in truth crossed
the intruder's height 0.99 m / 1.86 m away (NMAC). Point-mass closed loop, intruder sensed exactly."""

import numpy as np
import pytest

from avoidance.reachset.options import ReachSetOptions
from sim.core.threats import IntruderTrack
from tests.test_reachset_mission_end import fly


@pytest.mark.parametrize("vertical_margin", [2.0, 0.0])
def test_vertical_margin_keeps_a_pass_clear_of_the_nmac_cylinder_despite_a_low_height_estimate(vertical_margin):
    """Ownship north at 5 m/s, its estimate 3.7 m low; a 2 m/s intruder from ahead-left on
    course 135°, 2 m below the ownship, meeting it 2 m to the side after 15 s. With a 2 m
    vertical margin the true pass stays outside the 5 m / 2.5 m NMAC cylinder; without it the
    planner passes through the intruder's true height (2.3 m / 1.9 m here)."""
    course = np.radians(135.0)
    ivel = 2.0 * np.array([np.cos(course), np.sin(course), 0.0])
    meet = np.array([75.0, 2.0, -18.0])
    intruder = IntruderTrack("intruder", 0.0, meet - 15.0 * ivel, ivel, 0.45)
    cfg = ReachSetOptions(period=1.0, intruder_margin=4.55, intruder_margin_vertical=vertical_margin).avoidance_config()
    trace: list = []
    fly(
        [[150.0, 0.0, -16.3]],
        1.0,
        start=(0.0, 0.0, -20.0),
        speed=5.0,
        t_end=30.0,
        turns_in_place=True,
        cfg=cfg,
        intruder=intruder,
        estimate_error=(0.0, 0.0, 3.7),
        trace=trace,
    )
    own = np.array([p for _, p, _ in trace])
    other = np.array([q for _, _, q in trace])
    rel = other - own
    horizontal, vertical = np.hypot(rel[:, 0], rel[:, 1]), np.abs(rel[:, 2])
    nmac = bool(((horizontal < 5.0) & (vertical < 2.5)).any())
    assert nmac == (vertical_margin == 0.0)
    assert horizontal.min() < 20.0  # the pair did meet
