"""MPTP search parts: A* against brute force, visibility, turning geometry, goal interception,
nowcast files and the planner adapter."""

import itertools
import json
import math

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import box

from guidance.mptp.astar import astar
from guidance.mptp.config import MptpConfig
from guidance.mptp.goal import GoalTrack
from guidance.mptp.heuristics import GoalAvailability, edh
from guidance.mptp.planner import MptpPlanner
from guidance.mptp.search import default_workspace, plan_trajectory
from guidance.mptp.statespace import free_space, polygonal
from guidance.mptp.timeline import ObstacleTimeline
from guidance.mptp.turning import flyby_path, wrap
from guidance.mptp.visibility import (
    blocked,
    boundary_of,
    reduced_graph,
    tangent,
    visible_vertices,
)
from sim.core.mission import Mission
from sim.core.plan import PlanStatus, Threats
from sim.core.threats import StormSnapshot
from sim.geodesy import GeoPoint
from sim.nowcast_files import (
    NowcastError,
    dump_nowcast,
    load_nowcast,
    parse_nowcast,
    save_nowcast,
)
from sim.plan_geojson import plan_geojson
from sim.storm_synthetic import StormField
from sim.testbeds.mptp_openloop import vehicle_state


@st.composite
def graphs(draw):
    n = draw(st.integers(2, 7))
    pts = draw(st.lists(st.tuples(st.integers(0, 20), st.integers(0, 20)), min_size=n, max_size=n))
    pts = np.array(pts, float)
    edges = draw(st.sets(st.tuples(st.integers(0, n - 1), st.integers(0, n - 1)), max_size=20))
    w = {(a, b): float(np.linalg.norm(pts[a] - pts[b])) + draw(st.integers(0, 5)) for a, b in edges if a != b}
    return pts, w


@settings(max_examples=150, deadline=None)
@given(graphs(), st.sampled_from(["zero", "euclid"]))
def test_astar_is_optimal_against_brute_force(g, heuristic):
    pts, w = g
    n = len(pts)
    h = (lambda v: 0.0) if heuristic == "zero" else (lambda v: float(np.linalg.norm(pts[v] - pts[n - 1])))
    res = astar(
        0,
        lambda v: [(b, c, h(b)) for (a, b), c in w.items() if a == v],
        lambda v: v == n - 1,
        lambda v: v,
        10_000,
        h(0),
    )
    best = math.inf
    for k in range(n - 1):  # every simple path 0 -> n-1
        for mid in itertools.permutations(list(range(1, n - 1)), k):
            seq = (0, *mid, n - 1)
            if all((a, b) in w for a, b in itertools.pairwise(seq)):
                best = min(best, sum(w[a, b] for a, b in itertools.pairwise(seq)))
    if math.isinf(best):
        assert res.status == "exhausted"
    else:
        assert res.status == "ok" and res.cost == pytest.approx(best)
        assert sum(w[a, b] for a, b in zip(res.path, res.path[1:], strict=False)) == pytest.approx(best)


def test_astar_reports_the_expansion_limit():
    res = astar(0, lambda v: [(v + 1, 1.0, 0.0)], lambda v: v == 100, lambda v: v, 10)
    assert res.status == "limit" and res.expanded == 10


def test_astar_returns_the_best_partial_path_at_the_limit():
    """Two branches from 0: the even one gets closer to the goal (smaller h); at the limit the
    partial path ends at the expanded node with the smallest h that partial_ok accepts."""

    def expand(v):
        return [(v + 2, 1.0, 50.0 - v), (v + 1, 1.0, 100.0)] if v % 2 == 0 else []

    res = astar(0, expand, lambda v: v == 1000, lambda v: v, 5, partial_ok=lambda v: v <= 6)
    assert res.status == "limit" and res.partial == [0, 2, 4, 6]


def test_goal_availability_waits_for_the_goal_to_uncover():
    """A cell on the goal until it dissipates at 600 s: an arrival before then cannot happen, so
    the wait-aware EDH is the time to 600 s; after, the plain straight-line time."""
    cfg = MptpConfig(
        safety_single_m=(500.0,) * 3,
        safety_line_m=(500.0,) * 3,
        sigma_front_mps=0.0,
        sigma_back_mps=0.0,
        simplify_tol_m=50.0,
    )
    snaps = [
        StormSnapshot(300.0 * k, (box(-1000, -1000, 1000, 1000),) if k < 2 else (), np.zeros((1 if k < 2 else 0, 2)))
        for k in range(13)
    ]
    av = GoalAvailability(ObstacleTimeline(snaps, cfg, 7200.0), GoalTrack.fixed([0.0, 0.0]))
    np.testing.assert_allclose(av.earliest(np.array([0.0, 100.0, 590.0, 900.0])), [600.0, 600.0, 600.0, 900.0])
    h = edh(np.array([[26_000.0, 0.0], [2_600.0, 0.0]]), np.zeros(2), GoalTrack.fixed([0.0, 0.0]), 26.0, av)
    np.testing.assert_allclose(h, [1000.0, 600.0])


def _square_world():
    return boundary_of(box(-100, -100, 100, 100).difference(box(-10, -10, 10, 10)))


def test_tangents_visibility_and_reduced_graph_around_a_square():
    b = _square_world()
    assert len(b.verts) == 4  # the square's corners; the workspace corners are reflex
    _si, vi = visible_vertices(np.array([[-50.0, 0.0]]), b)
    assert sorted(map(tuple, b.verts[vi])) == [(-10.0, -10.0), (-10.0, 10.0)]
    i, _j, d = reduced_graph(b)
    assert len(i) == 4 and np.allclose(d, 20.0)  # the four body edges; diagonals are not bitangent
    p, q = np.array([[-50.0, 0.0], [-50.0, 0.0]]), np.array([[50.0, 0.0], [-50.0, 50.0]])
    assert blocked(p, q, b).tolist() == [True, False]
    assert tangent(np.array([[0.0, 50.0]]), b).sum() == 2


def test_flyby_path_respects_the_turn_radius():
    pts = np.array([[0.0, 0.0], [2000.0, 0.0], [3000.0, 1000.0], [3000.0, 3000.0]])
    path = flyby_path(pts, 0.0, 300.0)
    a, b, c = path[:-2], path[1:-1], path[2:]
    ab, bc, ca = (np.linalg.norm(x, axis=1) for x in (b - a, c - b, a - c))
    area2 = np.abs((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
    ok = (ab > 1e-6) & (bc > 1e-6)
    curvature = 2 * area2[ok] / (ab * bc * ca)[ok]
    assert curvature.max() <= 1 / 300.0 * (1 + 1e-6)
    assert np.allclose(path[-1], pts[-1])
    with pytest.raises(ValueError, match="does not fit"):
        flyby_path(np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 100.0]]), 0.0, 300.0)


def test_turn_radius_from_speed_and_bank():
    cfg = MptpConfig.thesis()
    assert cfg.turn_radius_m == pytest.approx(80.0**2 / (9.80665 * math.tan(math.radians(25.0))))
    assert MptpConfig().turn_radius_m == pytest.approx(26.0**2 / (9.80665 * math.tan(math.radians(20.0))))
    assert wrap(3 * math.pi / 2) == pytest.approx(-math.pi / 2)


def test_moving_goal_interception():
    goal = GoalTrack(np.array([0.0, 100.0]), np.array([[1000.0, 0.0], [1000.0, 500.0]]))
    t = goal.intercept(np.zeros((1, 2)), np.zeros(1), 10.0)[0]
    assert np.linalg.norm(goal.at(t)) == pytest.approx(10.0 * t)
    assert GoalTrack.fixed([300.0, 400.0]).intercept(np.zeros((1, 2)), np.array([5.0]), 10.0)[0] == 55.0


def test_nowcast_file_round_trip(tmp_path):
    snaps = StormField(seed=4, n_cells=5).nowcast(0.0, 900.0)
    for frame, origin in (("local_ne", None), ("wgs84", GeoPoint(47.5, 10.25))):
        save_nowcast(tmp_path / f"{frame}.json", snaps, frame, origin)
        back = load_nowcast(tmp_path / f"{frame}.json")
        assert [s.t for s in back] == [s.t for s in snaps]
        for a, b in zip(back, snaps, strict=False):
            assert shapely.hausdorff_distance(shapely.union_all(list(a.cells)), shapely.union_all(list(b.cells))) < 1.0
            assert np.allclose(a.velocities_ne, b.velocities_ne)


@pytest.mark.parametrize(
    "mutate,msg",
    [
        (lambda d: d.update(type="Feature"), "type: expected 'FeatureCollection'"),
        (lambda d: d.update(frame="utm"), "frame: 'utm'"),
        (lambda d: d["features"][1]["properties"].pop("t"), r"features\[1\].properties.t: expected a finite number"),
        (lambda d: d["features"][0]["properties"].update(t="soon"), r"features\[0\].properties.t"),
        (
            lambda d: d["features"][2].update(geometry={"type": "Point", "coordinates": [0, 0]}),
            r"features\[2\].geometry.type",
        ),
        (
            lambda d: d["features"][0]["geometry"].update(coordinates=[[[0, 0], [1, 1], [0, 1], [1, 0], [0, 0]]]),
            r"features\[0\].geometry.coordinates\[0\]: not a valid polygon",
        ),
        (lambda d: d["features"][0]["properties"].update(velocity_ne=[1.0]), r"features\[0\].properties.velocity_ne"),
        (lambda d: d["features"][0]["properties"].pop("velocity_ne"), "some cells have properties.velocity_ne"),
    ],
)
def test_nowcast_errors_name_the_feature_and_field(mutate, msg):
    doc = dump_nowcast(StormField(seed=4, n_cells=5).nowcast(0.0, 300.0))
    mutate(doc)
    with pytest.raises(NowcastError, match=msg):
        parse_nowcast(json.loads(json.dumps(doc)))


def test_planner_adapter_cadence_plan_fields_and_geojson():
    field = StormField(seed=5, n_cells=6, size_m=(60_000.0, 60_000.0), mean_radius_m=3000.0, births_after_t0=False)
    cfg = MptpConfig(max_expansions=200)
    mission = Mission(np.array([[60_000.0, 60_000.0, -100.0]]), cfg.tas_mps, 500.0)
    planner = MptpPlanner(mission, cfg)
    est = vehicle_state(0.0, np.array([0.0, 0.0]), math.radians(45.0), cfg.tas_mps)
    threats = Threats(storms=field.nowcast(0.0))
    plan = planner.plan(est, threats, 0.0)
    assert plan.status in (PlanStatus.OK, PlanStatus.DEGRADED)
    assert np.all(np.diff(plan.times) > 0) and plan.labels[-1] == 0 and (plan.labels[:-1] == -1).all()
    assert plan.positions[-1, 2] == pytest.approx(-100.0) and plan.velocities.shape == plan.positions.shape
    assert {"expanded", "runtime_s", "heuristic"} <= set(plan.diagnostics)
    assert planner.plan(est, threats, 100.0) is plan  # between replans the plan is kept
    assert planner.plan(est, threats, cfg.replan_period_s) is not plan
    doc = json.loads(plan_geojson(plan, GeoPoint(47.0, 8.0), planner.timeline.shape_at(0.0), threats.storms[0]))
    kinds = {f["properties"]["kind"] for f in doc["features"]}
    assert kinds == {"plan", "margin", "storm"}
    lon, lat = doc["features"][0]["geometry"]["coordinates"][0]
    assert lat == pytest.approx(47.0) and lon == pytest.approx(8.0)


def test_goal_covered_for_the_whole_horizon_gives_a_holding_orbit():
    cfg = MptpConfig(safety_single_m=(2000.0,) * 3, sigma_front_mps=0.0, sigma_back_mps=0.0)
    storm = StormSnapshot(0.0, (box(18_000, -3000, 24_000, 3000),), None)  # static cell on the goal
    mission = Mission(np.array([[21_000.0, 0.0, 0.0]]), cfg.tas_mps, 500.0)
    plan = MptpPlanner(mission, cfg).plan(
        vehicle_state(0.0, np.zeros(2), 0.0, cfg.tas_mps), Threats(storms=[storm]), 0.0
    )
    assert plan.status == PlanStatus.DEGRADED and plan.diagnostics["reason"] == "goal covered"
    assert plan.times[-1] >= cfg.replan_period_s and np.all(np.diff(plan.times) > 0)
    assert np.linalg.norm(plan.positions[:, :2] - plan.positions[0, :2], axis=1).max() < 3 * cfg.leg_m


def test_no_leg_from_a_boundary_vertex_into_the_obstacle():
    """A state on a corner of EX_obs, its course pointing into the obstacle: the auxiliary state
    straight ahead lies inside, and no edge crossing shows it (the leg starts on the boundary).
    The plan must go around, every leg outside the margins at its time."""
    cfg = MptpConfig(
        safety_single_m=(1000.0,) * 3,
        safety_line_m=(1000.0,) * 3,
        sigma_front_mps=0.0,
        sigma_back_mps=0.0,
        simplify_tol_m=50.0,
        heuristic="edh",
    )
    storm = box(10_000, -5_000, 20_000, 5_000)
    tl = ObstacleTimeline([StormSnapshot(0.0, (storm,), np.zeros((1, 2)))], cfg, 7200.0)
    goal = GoalTrack.fixed([30_000.0, 5_000.0])
    fs = free_space(
        tl,
        np.zeros(2),
        0.0,
        default_workspace(np.vstack([np.zeros(2), goal.at(0.0)]), cfg),
        cfg.tas_mps,
        cfg.ring_segments,
    )
    corner = fs.boundary.verts[np.argmin(np.linalg.norm(fs.boundary.verts - [9_000.0, -6_000.0], axis=1))]
    ahead = math.atan2(0.0 - corner[1], 15_000.0 - corner[0])  # towards the storm's centre
    traj = plan_trajectory(tl, corner, 0.0, ahead - cfg.course_change_max, goal, cfg)
    assert traj.status == "ok"
    margin = tl.shape_at(0.0).buffer(-1.0)  # legs along its edges graze it
    for p, q in zip(traj.positions[:-1], traj.positions[1:], strict=False):
        s = np.linspace(0.0, 1.0, 50)[:, None]
        pts = p + s * (q - p)
        assert not shapely.contains_xy(margin, pts[:, 0], pts[:, 1]).any(), f"leg {p} -> {q} enters the margins"


def test_polygonal_keeps_the_areas_of_a_collection_and_drops_its_lines():
    """Two margins that touch leave a line in their intersections' union: the obstacle is the
    polygons only (a collection has no boundary to escape a trapped state from)."""
    sq = box(0, 0, 10, 10)
    mixed = shapely.GeometryCollection([sq, shapely.LineString([(10, 0), (20, 0)]), shapely.Point(30, 30)])
    out = polygonal(mixed)
    assert out.geom_type == "Polygon" and out.equals(sq) and out.boundary is not None
    assert polygonal(sq) is sq
    assert polygonal(shapely.GeometryCollection([shapely.LineString([(0, 0), (1, 1)])])).is_empty
