"""Build a vehicle's planner from its scenario configuration (one place for the runner and for
re-running planners on a log)."""

from __future__ import annotations

from avoidance.follow_mission import FollowMissionPlanner
from avoidance.planner import Planner
from guidance.mission import Mission


def make_planner(kind: str, mission: Mission) -> Planner:
    """The planner called ``kind`` for ``mission``."""
    if kind == "follow_mission":
        return FollowMissionPlanner(mission)
    raise ValueError(f"unknown planner {kind!r}")
