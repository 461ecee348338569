"""World-level broad phase (sim/broad_phase.py): the k-d tree candidates and the exact test
against brute force, the planner's awareness against its own intruder culling, and the world
handing each vehicle only the traffic that can matter."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aircraft.registry import get_airframe
from avoidance.reachset.situation import Assessor
from sim.broad_phase import relevant
from sim.mcap_log import McapLog
from sim.planner_registry import make_planner, planner_awareness
from sim.scenario import load_scenario
from sim.vehicle_setup import mission_from_config
from sim.world import World


def brute(pos, speed, radius, awareness, settle_s):
    out = []
    for i, a in enumerate(awareness):
        others = [j for j in range(len(pos)) if j != i]
        if a is not None:
            reach, look = a[0], a[1] + settle_s
            others = [
                j for j in others if np.linalg.norm(pos[j] - pos[i]) <= reach + (speed[i] + speed[j]) * look + radius[j]
            ]
        out.append(others)
    return out


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(1, 12),
    n_vehicles=st.integers(1, 12),
    seed=st.integers(0, 2**31),
    settle_s=st.floats(0.0, 20.0),
)
def test_relevant_equals_the_brute_force_pair_test(n, n_vehicles, seed, settle_s):
    rng = np.random.default_rng(seed)
    n_vehicles = min(n_vehicles, n)
    pos = rng.uniform(-800, 800, (n, 3)) * rng.choice([0.1, 1.0, 20.0], (n, 1))
    speed = rng.uniform(0, 30, n) * (rng.random(n) < 0.8)
    radius = rng.uniform(0.2, 15.0, n)
    awareness = [None if rng.random() < 0.25 else (rng.uniform(10, 300), rng.uniform(1, 30)) for _ in range(n_vehicles)]
    got = relevant(pos, speed, radius, awareness, settle_s)
    assert [g.tolist() for g in got] == brute(pos, speed, radius, awareness, settle_s)


def test_settle_time_and_awareness_act():
    pos = np.array([[0.0, 0.0, 0.0], [500.0, 0.0, 0.0]])
    speed = np.array([5.0, 5.0])
    radius = np.array([0.45, 0.45])
    assert relevant(pos, speed, radius, [(60.0, 11.0)], 10.0)[0].tolist() == []  # 60 + 10·21 + 0.45 < 500
    assert relevant(pos, speed, radius, [(60.0, 11.0)], 40.0)[0].tolist() == [1]
    assert relevant(pos, speed, radius, [(300.0, 11.0)], 10.0)[0].tolist() == [1]
    assert relevant(pos, 4 * speed, radius, [(60.0, 11.0)], 10.0)[0].tolist() == [1]
    assert relevant(pos, speed, radius, [None], 10.0)[0].tolist() == [1]
    with pytest.raises(ValueError, match="broad phase"):
        relevant(pos, speed[:1], radius, [None])


def test_a_track_outside_the_awareness_is_culled_by_the_planner():
    """The reach-set planner's awareness (range, horizon) is conservative for its own culling:
    an intruder farther than range + (own + its speed) x horizon + its radius, in any direction,
    is never rated; just inside the range, head-on, it is."""
    scenario, _ = load_scenario("scenarios/reachset/s7_head_on.toml")
    cfg = scenario.vehicle[0]
    mission = mission_from_config(cfg, scenario.origin_point)
    planner = make_planner(cfg.planner.type, mission, get_airframe(cfg.aircraft).kind, cfg.planner.options)
    reach, horizon = planner.awareness()
    seg = planner.control.segment(0 if len(planner.control.sma.automata) == 1 else 1)
    assert reach >= seg.grid.range
    rng = np.random.default_rng(1)
    own_speed, speed, r = 5.0, 8.0, 0.45
    for assessor in seg.assessors.values():
        assert isinstance(assessor, Assessor)
        model = assessor.intruder_model
        dirs = rng.normal(size=(200, 3))
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        gap = reach + (own_speed + speed) * horizon + r + 1e-6 - float(seg.grid.steps[0])  # grid one movement ahead
        vel = -dirs * speed  # straight at the vehicle
        far = np.column_stack([dirs * gap, vel, np.full(200, r + planner.control.cfg.intruders.body_margin)])
        assert not model.reachable(far).any()
        near = np.array([[seg.grid.range, 0.0, 0.0, -speed, 0.0, 0.0, r]])
        assert model.reachable(near).all()


def sensed_ids(path: str, seconds: float, tmp_path) -> dict[str, set[str]]:
    """Ids of the tracks each vehicle holds after ``seconds`` of sensing (no flight needed)."""
    scenario, _ = load_scenario(path)
    log = McapLog(tmp_path / "w.mcap", scenario.epoch_ns)
    try:
        world = World(scenario, log)
        for k in range(int(seconds * scenario.logging.rate_hz) + 1):
            world.sense(k / scenario.logging.rate_hz)
        return {v.name: {tr.id for tr in v.threats.intruders} for v in world.vehicles}
    finally:
        log.close()


def test_the_world_hands_each_reachset_vehicle_only_its_partner(tmp_path):
    """Eight reach-set quadrotors in four head-on pairs 500 m apart: each tracks its partner only
    (before: all seven); in the mixed world the quadrotor does not track the HAPS 17.6 km above
    but does track the intruder once it can reach it, while the HAPS (no awareness: follow-mission planner)
    hears everyone."""
    ids = sensed_ids("scenarios/reachset_fleet8.toml", 3.0, tmp_path)
    for k in range(8):
        partner = f"uas{k + 2 if k % 2 == 0 else k}"
        assert ids[f"uas{k + 1}"] == {partner}
    early = sensed_ids("scenarios/mixed_haps_quad_reachset.toml", 3.0, tmp_path)
    assert early["quad"] == set()  # head_on 335 m away > 60 + (5 + 5)·(11 + 10) + 0.45
    assert early["haps"] == {"quad", "head_on"}
    later = sensed_ids("scenarios/mixed_haps_quad_reachset.toml", 20.0, tmp_path)
    assert later["quad"] == {"head_on"}  # 250 m away; "crossing" appears at 60 s


def test_awareness_comes_from_the_planner_registry():
    """The world asks the registry what each planner type needs sensed: the plain reach-set
    avoider its grid's (range, horizon); the reach-set planner under the rules of the air every
    track (it negotiates with each peer it hears), like the planners without an awareness."""
    got = {}
    for path in ("scenarios/reachset/s7_head_on.toml", "scenarios/rules/s10_head_on.toml"):
        scenario, _ = load_scenario(path)
        cfg = scenario.vehicle[0]
        mission = mission_from_config(cfg, scenario.origin_point)
        planner = make_planner(cfg.planner.type, mission, get_airframe(cfg.aircraft).kind, cfg.planner.options)
        got[path] = planner_awareness(cfg.planner.type, planner)
    reach, horizon = got["scenarios/reachset/s7_head_on.toml"]
    assert 0.0 < reach < 1000.0 and 0.0 < horizon < 60.0
    assert got["scenarios/rules/s10_head_on.toml"] is None
    assert planner_awareness("follow_mission", object()) is None
