"""The rule parts of issue #22: the right plane's linear projection (6.217), the overtake speed
change (6.202), peers predicted from their filed plans (intent) and weather cases (§7.5).
Frames: GCF = ENU [m]; the reach set's LCF (X+ heading, Y+ left) at a grid at the origin."""

from __future__ import annotations

import numpy as np
import pytest

from avoidance.reachset.frames import GridPose
from avoidance.reachset.movement import MovementType
from avoidance.rules.restrictions import right_plane_heading_mask
from tests.test_rules_utm import NAV


def _node(*buffer: MovementType) -> int:
    """The thesis tree's node reached by ``buffer`` (1 m movements at 1 m/s, ±15° per movement)."""
    return next(n for n in range(NAV.n_nodes) if NAV.buffer(n) == list(buffer))


def test_linear_projection_disables_a_path_that_ends_right_but_heads_left():
    """Collision point (20, -2): the line from the UAS runs 5.71° right of its heading, so a point
    (x, 0) straight ahead lies x·sin 5.71° = 0.0995·x left of the plane. With the 1 m tolerance,
    two Straight movements end at (2, 0): 0.20 m left, enabled by 6.216. Projected 10 s on at
    1 m/s from that end (6.217) it reaches (12, 0): 1.19 m left, beyond the tolerance: disabled.
    Right-Right ends at (1.91, -0.51) heading 30° right: its projection (10.57, -5.51) stays right."""
    pose, cp = GridPose(np.zeros(3), 0.0), np.array([20.0, -2.0, 0.0])
    straight2 = _node(MovementType.STRAIGHT, MovementType.STRAIGHT)
    right2 = _node(MovementType.RIGHT, MovementType.RIGHT)
    assert NAV.tip[straight2] == pytest.approx([2.0, 0.0, 0.0])
    plane = right_plane_heading_mask(NAV, pose, cp, tol=1.0)
    projected = right_plane_heading_mask(NAV, pose, cp, tol=1.0, horizon=10.0)
    assert not plane[straight2] and projected[straight2]
    assert not plane[right2] and not projected[right2]
    assert (projected >= plane).all() and projected.sum() > plane.sum()
    # 6.217 with a horizon too short to cross the tolerance: 2 + 7 = 9 m -> 0.90 m left, enabled
    assert not right_plane_heading_mask(NAV, pose, cp, tol=1.0, horizon=7.0)[straight2]
