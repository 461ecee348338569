"""Open-loop decisions (spec §6): grid runs against an obstacle ahead and a head-on intruder,
mission control (modes, waypoints, buffer replacement), the planner adapter and the scene."""

import dataclasses
import json

import numpy as np
import pytest

from avoidance.reachset.cache import reach_set
from avoidance.reachset.config import AvoidanceConfig, ExpansionConfig, MovementConfig, ReachSetConfig
from avoidance.reachset.frames import GridPose
from avoidance.reachset.fusion import Categories, SpaceClass
from avoidance.reachset.grid import AvoidanceGrid
from avoidance.reachset.gridrun import Steering, emergency_runs, grid_run
from avoidance.reachset.mission import MissionControl, Mode
from avoidance.reachset.movement import KinState, build_primitive_table, thesis_automaton
from avoidance.reachset.movement import MovementType as M
from avoidance.reachset.planner import ReachSetAvoider
from avoidance.reachset.record import decision_record, scene_update
from avoidance.reachset.situation import Assessor
from sim.core.mission import Mission
from sim.core.plan import PlanStatus, Threats
from sim.core.state import VehicleState
from sim.core.threats import IntruderTrack, LidarScan
from sim.scenario import ScenarioError, parse_scenario

CFG = AvoidanceConfig()
GRID = AvoidanceGrid(CFG.grid)
TREE = reach_set(GRID, build_primitive_table(MovementConfig()), CFG.avoidance)
POSE = GridPose.from_ned(np.zeros(3), 0.0)  # grid at the origin heading north
GOAL = POSE.ned_to_lcf(np.array([30.0, 0.0, 0.0]))


def wall_scan(north: float = 5.0, half_width: float = 1.5, half_height: float = 1.5) -> LidarScan:
    """Ray-cast a wall ⊥ north at ``north`` [m] with a 1° lattice covering the grid."""
    az, el = np.meshgrid(
        np.radians(np.arange(-50.0, 50.5, 1.0)), np.radians(np.arange(-35.0, 35.5, 1.0)), indexing="ij"
    )
    dirs = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), -np.sin(el)], axis=-1).reshape(-1, 3)
    rng = north / dirs[:, 0]
    p = dirs * rng[:, None]
    hit = (np.abs(p[:, 1]) <= half_width) & (np.abs(p[:, 2]) <= half_height) & (rng <= 30.0)
    return LidarScan(0.0, np.zeros(3), dirs, np.where(hit, rng, 30.0), hit, 30.0)


def path_ned(node: int) -> np.ndarray:
    return POSE.lcf_to_ned(TREE.path_samples(node))


def straight_node() -> int:
    keys = TREE.buffers()
    return max((n for n, k in enumerate(keys) if k and set(k) == {M.STRAIGHT}), key=lambda n: len(keys[n]))


def test_obstacle_ahead_picks_a_free_trajectory():
    parts = Assessor(GRID, TREE, CFG).assess(POSE, 0.0, Threats(lidar=wall_scan()))
    run = grid_run(GRID, TREE, parts, GOAL, Categories(), CFG.fusion.threshold)
    assert run.path.ok
    f = run.fused
    assert not f.node_ok[straight_node()]
    assert (f.space_class == SpaceClass.OCCUPIED).any() and (f.space_class == SpaceClass.UNCERTAIN).any()
    p = path_ned(run.path.node)
    through_wall = (np.abs(p[:, 0] - 5.0) < 0.3) & (np.abs(p[:, 1]) <= 1.5) & (np.abs(p[:, 2]) <= 1.5)
    assert not through_wall.any()
    cells = GRID.cell_index(TREE.path_samples(run.path.node)[1:])
    assert (f.space_class[cells] == SpaceClass.FREE).all()


def test_head_on_intruder_picks_an_avoiding_trajectory():
    intruder = IntruderTrack("i1", 0.0, np.array([12.0, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0]), radius_m=1.0)
    parts = Assessor(GRID, TREE, CFG).assess(POSE, 0.0, Threats(intruders=[intruder]))
    runs, sel = emergency_runs(GRID, TREE, parts, GOAL, CFG.fusion.threshold)
    assert sel == 0 and runs[0].categories.intruders
    assert not runs[0].fused.node_ok[straight_node()]
    node = runs[0].path.node
    samples = TREE.path_samples(node)
    t = np.linspace(0.0, TREE.depth[node] * TREE.period, len(samples))
    own = POSE.lcf_to_ned(samples)
    other = intruder.pos_ned + np.outer(t, intruder.vel_ned)
    assert np.linalg.norm(own - other, axis=1).min() > intruder.radius_m
    straight = POSE.lcf_to_ned(TREE.path_samples(straight_node()))
    t_s = np.linspace(0.0, TREE.depth[straight_node()] * TREE.period, len(straight))
    assert (
        np.linalg.norm(straight - (intruder.pos_ned + np.outer(t_s, intruder.vel_ned)), axis=1).min()
        < intruder.radius_m
    )


def test_last_resort_path_keeps_away_from_an_intruder_that_blocks_every_path():
    """A head-on intruder whose body (8 m) covers every trajectory: no intruder-free path; the
    obstacle path (step 7) is the full trajectory that stays clear longest, not the straight one
    to the goal through it: its closest approach to the intruder's centre is larger."""
    intruder = IntruderTrack("i1", 0.0, np.array([10.0, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0]), radius_m=8.0)
    parts = Assessor(GRID, TREE, CFG).assess(POSE, 0.0, Threats(intruders=[intruder]))
    runs, sel = emergency_runs(GRID, TREE, parts, GOAL, CFG.fusion.threshold)
    assert sel == 3 and not runs[2].path.ok  # only the obstacle path exists

    def closest(node: int) -> float:
        p = POSE.lcf_to_ned(TREE.path_samples(node))
        t = np.linspace(0.0, TREE.depth[node] * TREE.period, len(p))
        return float(np.linalg.norm(p - (intruder.pos_ned + np.outer(t, intruder.vel_ned)), axis=1).min())

    node = runs[sel].path.node
    assert node in TREE.leaves() and node != straight_node()
    assert closest(node) > closest(straight_node()) + 1.0


@pytest.mark.parametrize("give_way", [False, True])
def test_last_resort_path_maximises_the_predicted_closest_approach(give_way):
    """D-18/D-21: with the intruders dropped (no intruder-free path), the obstacle run's path is
    the full-length one whose closest approach to the intruders' predictions (body surface, brute
    force over every path sample at its time) is the largest; two intruders, one ahead and one
    from the right. On straight lines only (give-way rate 0) among all paths; with the give-way
    rate each intruder is also predicted turning right (Euler-integrated here), the clearance is
    the smaller of the two, and only paths never left of the heading compete."""
    rate = np.pi / 12 if give_way else 0.0
    cfg = dataclasses.replace(CFG, intruders=dataclasses.replace(CFG.intruders, give_way_turn_rate=rate))
    tracks = [
        IntruderTrack("i1", 0.0, np.array([10.0, 0.5, 0.0]), np.array([-1.0, 0.0, 0.0]), radius_m=8.0),
        IntruderTrack("i2", 0.0, np.array([6.0, 9.0, 1.0]), np.array([0.0, -1.0, 0.0]), radius_m=2.0),
    ]
    parts = Assessor(GRID, TREE, cfg).assess(POSE, 0.0, Threats(intruders=tracks))
    runs, sel = emergency_runs(GRID, TREE, parts, GOAL, cfg.fusion.threshold)
    assert sel == 3 and not runs[2].path.ok

    def predictions(tr: IntruderTrack, t: np.ndarray) -> list[np.ndarray]:
        straight = tr.pos_ned + np.outer(t, tr.vel_ned)
        if not give_way:
            return [straight]
        dt = t[1] - t[0]
        course = np.arctan2(tr.vel_ned[1], tr.vel_ned[0]) + rate * t[:-1]  # NED: a right turn is clockwise
        vh = np.hypot(tr.vel_ned[0], tr.vel_ned[1])
        step = np.stack([vh * np.cos(course), vh * np.sin(course), np.full_like(course, tr.vel_ned[2])], axis=1)
        return [straight, tr.pos_ned + np.vstack([np.zeros(3), np.cumsum(step * dt, axis=0)])]

    def closest(node: int) -> float:
        p = POSE.lcf_to_ned(TREE.path_samples(node))
        t = np.linspace(0.0, TREE.depth[node] * TREE.period, len(p))
        return min(
            float((np.linalg.norm(p - q, axis=1) - tr.radius_m).min()) for tr in tracks for q in predictions(tr, t)
        )

    def never_left(node: int) -> bool:
        yaw = {M.LEFT: 1, M.UP_LEFT: 1, M.DOWN_LEFT: 1, M.RIGHT: -1, M.UP_RIGHT: -1, M.DOWN_RIGHT: -1}
        return np.cumsum([yaw.get(m, 0) for m in TREE.buffer(node)]).max() <= 0

    leaves = TREE.leaves()
    cand = [n for n in leaves[runs[sel].fused.node_ok[leaves]] if not give_way or never_left(n)]
    chosen = runs[sel].path.node
    assert not give_way or never_left(chosen)
    assert closest(chosen) >= max(closest(n) for n in cand) - 0.05
    assert closest(chosen) > closest(straight_node()) + 1.0


def flying(t: float, pos_ned, vel_ned) -> VehicleState:
    """An estimate at ``t`` [s]: NED position [m] and velocity [m/s], level, 5 m above the origin."""
    return VehicleState(
        t=t,
        pos_ned=np.array(pos_ned, float),
        vel_ned=np.array(vel_ned, float),
        euler=np.zeros(3),
        rates_body=np.zeros(3),
        alt_msl_m=5.0,
        lat_deg=0.0,
        lon_deg=0.0,
    )


def kin(n: float, e: float = 0.0, t: float = 0.0) -> KinState:
    return KinState(np.array([e, n, 0.0]), np.array([0.0, 0.0, np.pi / 2]), t, 1.0)  # GCF, heading north


def test_mission_control_modes_waypoints_and_buffer():
    wps = np.array([[0.0, 1.5, 0.0], [0.0, 40.0, 0.0]])  # GCF (east, north, up)
    mc = MissionControl(wps, thesis_automaton(), CFG)
    d1 = mc.step(kin(0.0), Threats())
    assert "waypoint_reached:0" in d1.events and d1.goal_index == 1 and d1.mode == Mode.NAVIGATION
    assert d1.executing == M.STRAIGHT and "empty_buffer" in d1.events and len(d1.buffer) >= 9
    planned = list(d1.buffer)
    d2 = mc.step(kin(1.0, t=1.0), Threats())
    assert d2.executing == planned[0]  # the movement planned for this frame is kept
    wall = wall_scan(north=6.0)
    d3 = mc.step(
        kin(2.0, t=2.0),
        Threats(lidar=LidarScan(2.0, np.array([2.0, 0, 0]), wall.directions_ned, wall.ranges_m, wall.hit, 30.0)),
    )
    assert d3.mode == Mode.EMERGENCY and "mode:emergency" in d3.events and "obstacle" in d3.events
    assert d3.status == "ok" and d3.runs[d3.selected].categories == Categories()
    d4 = mc.step(kin(3.0, t=3.0), Threats())
    assert d4.mode == Mode.NAVIGATION and "mode:navigation" in d4.events
    np.testing.assert_allclose(d4.reference.times[:2], [3.0, 4.0])


def test_planner_adapter_returns_ned_plan_record_and_scene():
    mission = Mission(np.array([[20.0, 0.0, -5.0]]), cruise_speed=1.0, acceptance_radius=2.0)
    av = ReachSetAvoider(mission, thesis_automaton())
    est = flying(0.0, [0.0, 0.0, -5.0], [1.0, 0.0, 0.0])
    wall = wall_scan()
    scan = LidarScan(0.0, est.pos_ned, wall.directions_ned, wall.ranges_m, wall.hit, 30.0)
    plan = av.plan(est, Threats(lidar=scan), 0.0)
    assert plan.status == PlanStatus.OK and plan.planner == "reachset" and plan.diagnostics["mode"] == "emergency"
    assert plan.positions.shape == (len(plan.times), 3) and np.all(np.diff(plan.times) > 0)
    np.testing.assert_allclose(plan.positions[0], est.pos_ned)
    np.testing.assert_allclose(plan.positions[1], [1.0, 0.0, -5.0], atol=1e-9)  # executing Straight, north
    assert (plan.labels == -1).all()
    rec = decision_record(av.last_decision)
    json.dumps(rec)
    assert len(rec["cells"]["class"]) == 350 and rec["mode"] == "emergency" and rec["reference_ned"]
    scene = scene_update(av.last_decision, 1e9)
    ent = scene.entities[0]
    assert ent.frame_id == "ned" and len(ent.cubes) == int((np.array(rec["cells"]["class"]) != 0).sum())
    assert len(ent.lines[0].points) == len(av.last_decision.reference.positions)
    assert scene.SerializeToString()
    est_near = flying(15.0, [19.0, 0.0, -5.0], [1.0, 0.0, 0.0])
    near = av.plan(est_near, Threats(), 15.0)  # final approach: a leg ending exactly at the waypoint
    assert near.diagnostics["complete"] == 0 and near.labels.tolist() == [-1, 0]
    np.testing.assert_allclose(near.positions, [est_near.pos_ned, mission.waypoints[0]])
    assert mission.mark_reached(0, 16.0)  # the follower passed it
    done = av.plan(est_near, Threats(), 16.0)
    assert done.diagnostics["complete"] == 1 and done.labels.tolist() == [0]
    np.testing.assert_allclose(done.positions, mission.waypoints)


def test_goal_inside_the_turn_circle_is_flown_away_from_not_orbited():
    """A goal beside the vehicle deep inside its turn circle (R = 3.82 m for the thesis set, more
    than the 2 m reach radius inside) that no movement end comes within the reach radius of:
    alg. 6.6 alone steers at the outer cell nearest to it (full turn: an orbit around it); with
    the MA's steering the path goes straight ahead (the goal then leaves the circle behind the
    vehicle). Goals ahead or near the circle's rim are steered at as before."""
    steering = Steering(build_primitive_table(MovementConfig()).turn_radii, 2.0)
    assert np.allclose(steering.turn_radii, 1.0 / (np.pi / 12))
    parts = Assessor(GRID, TREE, CFG).assess(POSE, 0.0, Threats())
    beside = np.array([0.5, -3.0, 0.0])  # LCF: just ahead, 3 m to the right
    assert steering.in_turn_circle(beside)
    assert steering.in_turn_circle(np.array([1.0, 0.0, -3.0]))  # below: the vertical circle
    assert not steering.in_turn_circle(np.array([0.5, -8.0, 0.0]))  # outside
    assert not steering.in_turn_circle(np.array([2.0, -1.5, 0.0]))  # inside, within reach of the rim
    plain = grid_run(GRID, TREE, parts, beside, Categories(), CFG.fusion.threshold)
    steered = grid_run(GRID, TREE, parts, beside, Categories(), CFG.fusion.threshold, steering)
    assert not plain.path.away and steered.path.away
    assert set(TREE.buffer(plain.path.node)) - {M.STRAIGHT}  # full turn towards the goal
    assert set(TREE.buffer(steered.path.node)) == {M.STRAIGHT}
    ahead = grid_run(GRID, TREE, parts, GOAL, Categories(), CFG.fusion.threshold, steering)
    assert not ahead.path.away


def test_lidar_shorter_than_the_grid_is_a_scenario_error(scenario_data):
    """A LiDAR whose range ends inside the reach-set grid leaves its far cells Uncertain, which
    blocks every path: the scenario is refused with one line naming the field."""
    data = scenario_data("reachset/building_lidar")
    parse_scenario(data)  # 60 m covers the 50 m grid of 5 m movements
    data["vehicle"][0]["lidar"] = {"max_range_m": 10.0}
    with pytest.raises(
        ScenarioError, match=r"vehicle\[0\]: lidar.max_range_m: 10 m does not cover the reach-set grid \(50 m"
    ):
        parse_scenario(data, "x.toml")


def test_emergency_path_keeps_its_course_while_feasible():
    """Frame 2 of a head-on encounter (ACAS-like horizontal sets, where a path's remaining
    movements are mostly a path of the set again): the first path's remaining movements are still
    feasible, so they stay the start of the new path (re-choosing freely flipped between sides)."""
    acas = ReachSetConfig.single(ExpansionConfig.acas(("horizontal",)))
    wps = np.array([[0.0, 40.0, 0.0]])  # GCF (east, north, up): straight ahead
    mc = MissionControl(wps, thesis_automaton(), dataclasses.replace(CFG, navigation=acas, avoidance=acas))
    threats = Threats(
        intruders=[IntruderTrack("i1", 0.0, np.array([12.0, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0]), radius_m=1.0)]
    )
    s1 = kin(0.0)
    d1 = mc.step(s1, threats)
    assert d1.mode == Mode.EMERGENCY and len(d1.buffer) > 2
    s2 = mc.sma.automata[0].apply(s1, d1.executing)
    d2 = mc.step(KinState(s2.pos, np.array([0.0, 0.0, s2.att[2]]), 1.0, 1.0), threats)
    assert d2.executing == d1.buffer[0]
    assert "keep_course" in d2.events and d2.buffer[: len(d1.buffer) - 1] == d1.buffer[1:]


def test_planning_heading_is_the_planned_one_within_a_yaw_increment():
    """At the next frame the adapter plans from the heading its last decision planned for now
    while the measured course is within one movement's yaw increment (15°) of it, else from
    the measured course (velocity)."""
    mission = Mission(np.array([[40.0, 0.0, -5.0]]), cruise_speed=1.0, acceptance_radius=2.0)
    av = ReachSetAvoider(mission, thesis_automaton())
    est = flying(0.0, [0.0, 0.0, -5.0], [1.0, 0.0, 0.0])
    av.plan(est, Threats(), 0.0)
    planned = av.last_decision.pose.psi  # heading at t = 1 s (GCF)

    def course(deg: float) -> VehicleState:
        v = np.array([np.cos(np.radians(deg)), np.sin(np.radians(deg)), 0.0])  # NED, from north
        return flying(1.0, [1.0, 0.0, -5.0], v)

    assert av.kin_state(course(10.0), 1.0).att[2] == pytest.approx(planned)
    assert av.kin_state(course(30.0), 1.0).att[2] == pytest.approx(np.pi / 2 - np.radians(30.0))
    assert av.kin_state(course(10.0), 1.5).att[2] == pytest.approx(np.pi / 2 - np.radians(10.0))  # not a frame time


def test_a_vehicle_moving_backwards_plans_from_its_yaw():
    """A multirotor pulled backwards (the first plan started at a misaligned first estimate, and
    the position loop chases it) plans along its yaw, not its course: planned along the course, the
    reach sets turned it the whole way round (S11 seed 17: 38 m off its line). A course within 90°
    of the yaw (crab, drift) is still the heading."""
    mission = Mission(np.array([[-40.0, 0.0, -5.0]]), cruise_speed=5.0, acceptance_radius=2.0)
    av = ReachSetAvoider(mission, thesis_automaton(), turns_in_place=True)
    south = np.pi  # NED yaw
    backwards = dataclasses.replace(flying(1.0, [0.0, 0.0, -5.0], [2.8, 0.4, 0.0]), euler=np.array([0.0, 0.0, south]))
    assert av.kin_state(backwards, 1.0).att[2] == pytest.approx(-np.pi / 2)  # GCF: south
    crab = dataclasses.replace(backwards, vel_ned=np.array([-2.8, 1.6, 0.0]))  # 30° off the yaw
    assert av.kin_state(crab, 1.0).att[2] == pytest.approx(np.arctan2(-2.8, 1.6))
