"""The central UTM authority's parts (sim/utm_authority.py): filed plans, the trajectory case of
two diverging plans, the scenario's utm options' errors, the monitoring of mandates."""

import re
from typing import Any

import jsonschema
import numpy as np
import pytest

from avoidance.utm.collision_case import UtmConfig, compute_collision_case
from avoidance.utm.notification import PositionNotification, Registration
from sim import log_schemas as S
from sim.core.frames import ned_to_enu
from sim.replay.decision_trail import authority_rows
from sim.replay.runlog import RunLog
from sim.scenario import ScenarioError, parse_scenario


def test_filed_plan_flies_the_waypoints_at_cruise_and_holds_at_the_last():
    """The authority's filing (cruise 2 m/s, whatever the vehicle's current speed), ENU."""
    still = PositionNotification(3.0, Registration("q"), np.zeros(3), np.zeros(3), True)
    plan = ned_to_enu(np.array([[10.0, 0.0, 0.0], [10.0, 10.0, -5.0]]))  # north 10 m, then east 10 m and up 5 m
    filed = still.with_intent(plan, 12.0, 1.0, speed=2.0)
    pts, times = filed.trajectory, filed.trajectory_t
    assert pts is not None and times is not None
    assert times[0] == 3.0 and times[-1] == 15.0 and len(times) == 13
    assert np.allclose(pts[5], [0.0, 10.0, 0.0])  # 10 m north at 5 s: ENU (east, north, up)
    assert np.allclose(pts[-1], [10.0, 10.0, 5.0])  # held at the last waypoint (path 21.2 m < 24 m flown)
    done = still.with_intent(np.empty((0, 3)), 12.0, 1.0, speed=2.0)  # no waypoint left: holds where it is
    assert done.trajectory is not None and np.allclose(done.trajectory, 0.0)


def plan_note(name: str, p0, v) -> PositionNotification:
    t = np.arange(0.0, 21.0)
    traj = np.asarray(p0, float) + np.outer(t, v)
    return PositionNotification(0.0, Registration(name), traj[0], np.asarray(v, float), True, traj, t)


def test_diverging_filed_plans_within_the_margin_open_no_case():
    """Two plans already past their closest approach: the trajectory minimum is at the frame
    time (t_cpa = 0); linearly they are diverging. No flag (a flag there re-opened a passed
    converging pair as head-on at the authority)."""
    a, b = plan_note("a", (0, 0, 0), (-1.0, 0, 0)), plan_note("b", (30, 0, 0), (1.0, 0, 0))
    case = compute_collision_case(a, b, 0.0, UtmConfig(time_margin=20.0))
    assert case is not None and case.trajectory and case.t_cpa == 0.0 and case.distance == 30.0
    assert not case.flagged
    c, d = plan_note("c", (0, 0, 0), (1.0, 0, 0)), plan_note("d", (30, 0, 0), (-1.0, 0, 0))  # converging
    meet = compute_collision_case(c, d, 0.0, UtmConfig(time_margin=20.0))
    assert meet is not None and meet.flagged


QUAD: dict[str, Any] = {
    "name": "q",
    "aircraft": "quadrotor",
    "initial": {"altitude": 20.0},
    "mission": {"cruise_speed": 2.0, "waypoints": [{"north": 5.0, "east": 0.0, "altitude": 20.0}]},
}
MANDATE = {"id": "m1", "vehicle": "q", "at": 1.0, "north": 5.0, "east": 0.0, "radius": 3.0}
BASE: dict[str, Any] = {
    "name": "u",
    "seed": 1,
    "duration": 5.0,
    "origin": {"lat": 47.0, "lon": 8.0},
    "vehicle": [QUAD],
}


@pytest.mark.parametrize(
    "change, message",
    [
        ({"vehicle": [{**QUAD, "utm_link": {}}]}, "vehicle[0].utm_link needs the [utm] section"),
        ({"utm": {"frame": 2.0, "lost_after": 1.0}}, "lost_after (1 s) must be at least one frame (2 s)"),
        ({"utm": {"frame": 0.05}}, "utm.frame: 0.05 s is shorter than a log tick (0.1 s)"),
        (
            {"utm": {"spoof": [{"vehicle": "x", "peer": "g", "at": 0.0, "north": 0, "east": 0, "altitude": 0}]}},
            "utm.spoof[0].vehicle: no vehicle 'x'",
        ),
        (
            {"utm": {}, "vehicle": [{**QUAD, "utm_link": {"outage": [{"start": 2.0, "end": 1.0}]}}]},
            "end (1 s) must be after start (2 s)",
        ),
        ({"utm": {}, "vehicle": [{**QUAD, "utm_link": {"loss": 1.0}}]}, "loss"),
        ({"vehicle": [{**QUAD, "peer_link": {}}]}, "vehicle[0].peer_link needs the [utm] section"),
        ({"utm": {}, "vehicle": [{**QUAD, "peer_link": {"latency": "1 m"}}]}, "vehicle[0].peer_link.latency"),
        ({"utm": {"mandate": [{**MANDATE, "vehicle": "x"}]}}, "utm.mandate[0].vehicle: no vehicle 'x'"),
        ({"utm": {"mandate": [{**MANDATE, "radius": 0.0}]}}, "utm.mandate[0].radius"),
        (
            {"utm": {"mandate": [{**MANDATE, "altitude_min": 500.0, "altitude_max": 400.0}]}},
            "altitude_max (400 m) must be above altitude_min (500 m)",
        ),
        ({"utm": {"mandate": [MANDATE, MANDATE]}}, "utm.mandate ids must be unique, repeated: m1"),
        ({"utm": {"mandate": [{**MANDATE, "shape": "box"}]}}, "utm.mandate[0].shape"),
    ],
)
def test_bad_utm_options_are_one_line_errors(change, message):
    with pytest.raises(ScenarioError, match=re.escape(message)):
        parse_scenario({**BASE, **change})
    parse_scenario({**BASE, "utm": {}})  # the section alone is valid
    parse_scenario({**BASE, "utm": {"mandate": [MANDATE]}, "vehicle": [{**QUAD, "peer_link": {}}]})


def test_a_vehicle_notified_inside_a_mandate_is_reported_once_as_a_breach(fly, tmp_path):
    """The authority monitors its mandates: q (which only notifies) flies inside the cylinder of
    a mandate from 1 s; one breach naming the vehicle and the mandate, in the decision trail too."""
    run = fly({**BASE, "duration": 4.0, "utm": {"mandate": [{**MANDATE, "north": 0.0, "radius": 10.0}]}})
    log = RunLog(run.path)
    (b,) = log.topic("/utm/breach").messages
    jsonschema.validate(b, S.UTM_BREACH)
    assert b["vehicle"] == "q" and b["mandate"]["id"] == "m1" and 1.0 <= b["t"] <= 2.0
    assert any(what == "breach of mandate m1 by q" for _, _, who, what in authority_rows(log) if who == "utm")
