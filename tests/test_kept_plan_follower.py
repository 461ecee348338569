"""A planner that keeps its plan between calls (the MPTP between replans, and whenever it keeps
the plan being flown) hands the follower the same plan object: the follower must go on from
where it is on it, not start again at its first leg.

Before, the vehicle handed the plan over at every planner call and the fixed-wing follower
restarted at leg 0, re-passing the legs whose end the aircraft had passed: after a turn of more
than 90 degrees the aircraft is back behind the end of the leg before it, so it was sent back
to that leg (in scenarios/mptp/corridor_opens.toml the HAPS left its planned holds that way)."""

import dataclasses

import numpy as np
import pytest

from avoidance.follow_mission import FollowMissionPlanner
from sim.core.plan import Plan, Threats
from sim.core.state import VehicleState
from sim.planner_registry import PLANNERS

pytestmark = pytest.mark.closed_loop


class _KeptPlan(FollowMissionPlanner):
    """The follow_mission plan made at the first call, returned at every call."""

    def plan(self, estimate: VehicleState, threats: Threats, t: float) -> Plan:
        if not hasattr(self, "kept"):
            self.kept = super().plan(estimate, threats, t)
        return self.kept


@pytest.mark.parametrize("kept", [True, False])
def test_an_out_and_back_plan_kept_between_calls_is_flown_to_its_end(fly, scenario_data, monkeypatch, kept):
    """The HAPS flies 2 km north, turns 153 degrees (switching 250 m early, it turns short of
    the first leg's end) and comes back; planner called every second. With the plan kept it
    completes as with a new plan per call; restarted at leg 0 it was sent north again at every
    call and never came back."""
    if kept:
        entry = PLANNERS["follow_mission"]
        monkeypatch.setitem(
            PLANNERS, "follow_mission", dataclasses.replace(entry, build=lambda o, c: _KeptPlan(c.mission))
        )
    data = scenario_data("haps_box_mission")
    data["duration"] = "300 s"
    data["vehicle"][0]["mission"]["waypoints"] = [
        {"north": "2 km", "east": 0, "altitude": "18 km"},
        {"north": 0, "east": "1 km", "altitude": "18 km"},
    ]
    run = fly(data, "out_and_back")
    assert run.result.status == "completed"
    truth = run.log.topic("/haps/truth/state")
    end = np.linalg.norm(truth["pos_ned"][-1, :2] - [0.0, 1000.0])
    assert end < 250.0 + 26.0  # within the acceptance radius (+ one second of flight)
    legs = run.log.topic("/haps/ctrl/setpoint")["leg"]
    if kept:
        assert np.all(np.diff(legs) >= 0), "the follower went back to an earlier leg of the kept plan"
