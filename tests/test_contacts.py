"""Crash detection from true states (sim/contacts.py, sim/hull.py) on hand-made states: the
quadrotor's JSBSim contact hull, the sink-rate limit at first touch (per plant step), swept
obstacle and body-body tests between two checks."""

import math

import numpy as np
import pytest
from shapely.geometry import Polygon

from aircraft.registry import get_airframe
from sim.contacts import Bodies, ContactMonitor, GroundWatch, _pairs_within
from sim.core.threats import PrismObstacle
from sim.hull import load_hull

QUAD = get_airframe("quadrotor")
HULL = load_hull(QUAD.jsbsim_file)
GEAR_DEPTH = 0.1524  # the quadrotor's gear contacts below its CG [m] (quadrotor.xml)
NONE = Bodies([], np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))


def monitor(n: int = 1, obstacles: list[PrismObstacle] | None = None) -> ContactMonitor:
    watches = [GroundWatch(HULL, QUAD.crash_sink_mps) for _ in range(n)]
    return ContactMonitor([f"q{i}" for i in range(n)], np.full(n, QUAD.radius_m), watches, obstacles or [])


def check(m: ContactMonitor, t: float, pos, vel=(0.0, 0.0, 0.0), others=NONE):
    pos = np.atleast_2d(np.asarray(pos, float))
    return m.check(t, pos, np.broadcast_to(np.asarray(vel, float), pos.shape), others)


def test_hull_is_the_models_contact_points():
    gear, pts = np.array(HULL.gear), np.array(HULL.points)
    assert gear.sum() == 3 and (~gear).sum() == 5
    assert np.allclose(pts[gear, 2], GEAR_DEPTH)  # below the CG: +down
    level = np.array(HULL.heights(GEAR_DEPTH, 0.0, 0.0))
    assert np.allclose(level[gear], 0.0) and (level[~gear] > 0.15).all()
    assert HULL.touching(GEAR_DEPTH, 0.0, 0.0) == (True, False)
    inverted = np.array(HULL.heights(0.1, math.pi, 0.0))
    assert inverted[~gear].min() == pytest.approx(0.1 - 0.06)  # the top plate lowest
    assert HULL.touching(0.05, math.pi, 0.0) == (True, True)


@pytest.mark.parametrize(("sink", "crash"), [(QUAD.crash_sink_mps - 0.1, False), (QUAD.crash_sink_mps + 0.1, True)])
def test_gear_touchdown_is_a_crash_only_above_the_sink_limit(sink, crash):
    w = GroundWatch(HULL, QUAD.crash_sink_mps)
    w.observe(0.0, 0.5, 0.0, 0.0, np.array([0.0, 0.0, sink]))
    w.observe(1 / 240, GEAR_DEPTH - 0.01, 0.0, 0.0, np.array([0.0, 0.0, 0.2]))  # springs already slowing it
    assert (w.crash is not None) is crash
    if crash:
        assert w.crash == (1 / 240, pytest.approx(sink))  # the speed at the step before contact


def test_resting_on_the_gear_is_not_a_crash_but_tipping_over_is():
    w = GroundWatch(HULL, QUAD.crash_sink_mps)
    for k in range(5):
        w.observe(k / 240, GEAR_DEPTH - 0.002, 0.0, 0.0, np.zeros(3))
    assert w.crash is None
    w.observe(5 / 240, 0.1, math.radians(80), 0.0, np.array([0.0, 0.5, 0.0]))
    assert w.crash == (5 / 240, 0.5)


def test_far_from_the_ground_the_hull_is_not_placed_and_forgets_its_speed():
    w = GroundWatch(HULL, QUAD.crash_sink_mps)
    w.observe(0.0, 0.5, 0.0, 0.0, np.array([0.0, 0.0, 10.0]))
    w.observe(0.1, w.near_m + 0.1, math.pi, 0.0, np.zeros(3))  # inverted, but far up: nothing
    w.observe(0.2, GEAR_DEPTH - 0.01, 0.0, 0.0, np.array([0.0, 0.0, 1.0]))
    assert w.crash is None  # judged on its own 1 m/s, not the 10 m/s before it left


def test_ground_crashes_are_reported_once_by_the_monitor():
    m = monitor(2)
    m.ground[1].crash = (0.01, 12.0)
    found = check(m, 0.02, [(0, 0, -20), (5, 0, -0.1)])
    assert [(c.vehicle, c.kind, c.t, c.impact_speed_mps) for c in found] == [("q1", "ground", 0.01, 12.0)]
    assert check(m, 0.04, [(0, 0, -20), (5, 0, -0.1)]) == []


def wall(top_up: float = 50.0) -> PrismObstacle:
    return PrismObstacle("wall", Polygon([(10, -5), (10.2, -5), (10.2, 5), (10, 5)]), 0.0, top_up)


def test_obstacle_crossed_between_two_checks_is_hit():
    m = monitor(obstacles=[wall()])
    assert check(m, 0.0, (9.0, 0, -20)) == []
    found = check(m, 0.1, (11.0, 0, -20), vel=(20.0, 0, 0))  # jumped through the 0.2 m wall
    assert [(c.kind, c.hit, c.impact_speed_mps) for c in found] == [("obstacle", "wall", 20.0)]


def test_obstacle_passed_over_or_beside_is_not_hit():
    m = monitor(obstacles=[wall(top_up=19.0)])
    assert check(m, 0.0, (9.0, 0, -20)) == []
    assert check(m, 0.1, (11.0, 0, -20)) == []  # 1 m above the top, radius 0.45 m
    m = monitor(obstacles=[wall()])
    assert check(m, 0.0, (9.0, 6.0, -20)) == []
    assert check(m, 0.1, (11.0, 6.0, -20)) == []  # 1 m beside its end


def test_two_vehicles_crossing_between_checks_both_crash():
    m = monitor(2)
    assert check(m, 0.0, [(0, 0, -20), (4, 0, -20)]) == []
    found = check(m, 0.1, [(4, 0, -20), (0, 0, -20)], vel=[(40, 0, 0), (-40, 0, 0)])
    assert sorted((c.vehicle, c.kind, c.hit, c.impact_speed_mps) for c in found) == [
        ("q0", "vehicle", "q1", 80.0),
        ("q1", "vehicle", "q0", 80.0),
    ]


def test_vehicles_passing_apart_and_objects_are_judged_by_their_radii():
    m = monitor(2)
    assert check(m, 0.0, [(0, 0, -20), (4, 1.0, -20)]) == []
    assert check(m, 0.1, [(4, 0, -20), (0, 1.0, -20)]) == []  # 1.0 m > 0.9 m apart
    balloon = Bodies(["balloon"], np.array([[4.0, 3.5, -20.0]]), np.zeros((1, 3)), np.array([2.0]))
    found = check(m, 0.2, [(4, 1.2, -20), (0, 1.0, -20)], others=balloon)  # 2.3 m < 2.45 m
    assert [(c.vehicle, c.kind, c.hit) for c in found] == [("q0", "object", "balloon")]


def test_quadrotor_dropped_on_its_back_rests_on_its_hull_with_finite_states():
    """The model's STRUCTURE contacts carry it: without them it sank through the ground until a
    gear foot, metres deep, threw it back out (non-finite rates within 0.05 s)."""
    from sim.geodesy import GeoPoint
    from sim.jsbsim_plant import InitialConditions, JSBSimPlant

    ground = GeoPoint(47.0, 8.0, 400.0)
    plant = JSBSimPlant(QUAD.jsbsim_model, 1.0 / QUAD.plant_hz, ground, QUAD.folder)
    plant.initialise(
        InitialConditions(GeoPoint(47.0, 8.0, 402.0), roll_rad=math.radians(170), terrain_alt_m=ground.alt_m)
    )
    ups = []
    for _ in range(3 * QUAD.plant_hz // 10):
        plant.step(10)
        s = plant.truth()
        assert np.isfinite(np.concatenate([s.pos_ned, s.vel_ned, s.rates_body])).all()
        ups.append(s.alt_msl_m - ground.alt_m)
    top = min(h for h, g in zip(HULL.heights(0.0, math.pi, 0.0), HULL.gear, strict=True) if not g)  # top plate
    assert min(ups) > 0.0 and ups[-1] == pytest.approx(-top, abs=0.02)


@pytest.mark.parametrize("seed", range(5))
def test_direct_pair_search_finds_the_k_d_trees_pairs(monkeypatch, seed):
    """Candidate pairs among 12 vehicles and 30 objects in a 10 m cube, and the crashes over
    one 0.1 s check: the direct distances (small worlds), the k-d tree (large ones) and a plain
    double loop agree."""
    rng = np.random.default_rng(seed)
    n, m = 12, 30
    p0 = rng.uniform(0.0, 10.0, (n + m, 3))
    vel = rng.normal(0.0, 5.0, (n + m, 3))
    p1 = p0 + 0.1 * vel
    radii = rng.uniform(0.2, 1.5, m)
    reach = 4.0
    loop = [(a, b) for a in range(n) for b in range(a + 1, n + m) if np.linalg.norm(p1[a] - p1[b]) <= reach]
    assert 0 < len(loop) < n * (n + m) // 2

    def found(direct_pairs: int) -> tuple[list, list]:
        monkeypatch.setattr("sim.contacts._DIRECT_PAIRS", direct_pairs)
        mon = monitor(n)
        ids = [f"o{k}" for k in range(m)]
        check(mon, 0.0, p0[:n], vel[:n], Bodies(ids, p0[n:], vel[n:], radii))
        crashes = check(mon, 0.1, p1[:n], vel[:n], Bodies(ids, p1[n:], vel[n:], radii))
        return list(zip(*(a.tolist() for a in _pairs_within(p1, n, reach)), strict=True)), crashes

    (direct, crashes), (tree, tree_crashes) = found(1 << 20), found(0)
    assert direct == tree == loop
    assert crashes, "the crowd must produce crashes for the comparison to mean anything"
    assert crashes == tree_crashes
