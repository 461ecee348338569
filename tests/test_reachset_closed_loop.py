"""Closed-loop reach-set scenarios (spec §9.3) flown by the JSBSim quadrotor on its EKF estimate;
numbers read back from the MCAP by the replay metrics."""

import pytest

from sim.replay.report import log_metrics

pytestmark = pytest.mark.closed_loop

MAP_MARGIN_M = 0.5  # MapConfig.safety_margin


@pytest.mark.parametrize("name", ["building", "building_lidar"])
def test_building_is_avoided_and_the_mission_completes(fly, name):
    """S1 leg without and with a LiDAR covering the grid (measured clearance 8.2 m / 9.8 m; with
    the LiDAR, seen free space erases the map's margin (6.158) and the detected faces rate the
    building)."""
    m = log_metrics(fly(f"reachset/{name}").log)["vehicles"]["quad"]
    assert m["mission"]["complete"]
    assert 40.0 <= m["mission"]["time_s"] <= 40.0 * 1.5  # 200 m at 5 m/s, detour within +50 %
    clearance = m["clearance"]["obstacle.building"]["distance_m"]
    assert clearance > MAP_MARGIN_M


SCALE = 5.0  # the encounter files are the thesis' geometry x5 (L = 5 m, scenarios/reachset/generate.py)
SEPARATION_LINE_M = 1.2 * SCALE  # spec §9.3 S6/S7: minimum separation above the 1.2 m line


@pytest.mark.parametrize("name", ["s6_converging", "s7_head_on"])
def test_non_cooperative_encounter_keeps_separation_and_both_complete(fly, name):
    """S6/S7: two JSBSim quadrotors, each sensing the other only through the surveillance model
    (reports -> track -> intruder), keep their minimum 3-D separation (truth, from the MCAP) above
    the emergency line and both reach their waypoint within the thesis' ~40 s (x1.5)."""
    m = log_metrics(fly(f"reachset/{name}").log)
    for v in ("uas1", "uas2"):
        assert m["vehicles"][v]["mission"]["complete"], v
        assert m["vehicles"][v]["mission"]["time_s"] <= 40.0 * 1.5
    sep = m["separation"]["uas1-uas2"]["distance_m"]
    assert sep > SEPARATION_LINE_M
    assert sep < 40.0  # they did meet: the encounter is not avoided by never coming close


# In CI the maze (30 buildings); the slalom slow
@pytest.mark.parametrize(
    ("name", "thesis_s", "buildings"),
    [pytest.param("s2_slalom", 101.0, 15, marks=pytest.mark.slow), ("s3_maze", 103.0, 30)],
)
def test_maze_s2_s3_rides_the_envelope_and_completes(fly, name, thesis_s, buildings):
    """S2 (slalom, goal hidden behind a building) and S3 (maze) at L = 5 m: the buildings are
    keep-out geofences with the thesis' 2.5 m margin x5; pass (spec §9.3): completes, never
    inside a body, clearance to every building >= margin - 0.5 m x5, mission time within ±15 %
    of the thesis' 101 s / 103 s (measured: S2 90.6 s, closest 14.3 m; S3 108.4 s, closest
    14.9 m, through the maze's corridors since the target cells are ranked by the cost-to-go
    around the known buildings, D-17)."""
    m = log_metrics(fly(f"reachset/{name}").log)["vehicles"]["quad"]
    assert m["mission"]["complete"]
    assert thesis_s * 0.85 <= m["mission"]["time_s"] <= thesis_s * 1.15
    clear = {k: v["margin_m"] for k, v in m["clearance"].items() if k.startswith("geofence.")}
    assert len(clear) == buildings
    assert min(clear.values()) >= (2.5 - 0.5) * SCALE


def test_trap_s5_is_left_round_the_outside(fly):
    """S5 (trap, spec §9.3 regression: must not end in the trap pocket) at L = 5 m: a PentaTrap
    100 m across whose pocket opens towards the start, the waypoint behind it. With the target
    cells ranked by the straight distance the vehicle circled in the pocket for ever; ranked by
    the cost-to-go around the known building (D-17) it completes (measured 85.5 s, closest
    26.2 m to the body, margin 25 m)."""
    m = log_metrics(fly("reachset/s5_trap").log)["vehicles"]["quad"]
    assert m["mission"]["complete"]
    assert m["mission"]["time_s"] <= 300.0 / 5.0 * 2.0  # 300 m at 5 m/s, the way round within x2
    assert m["clearance"]["geofence.trap"]["margin_m"] >= (5.0 - 0.5) * SCALE


@pytest.mark.parametrize("mode", ["polygon", "circle"])
def test_storm_s4_moving_constraint_keeps_its_margin_and_completes(fly, scenario_data, mode):
    """S4 (moving storm seen through the weather nowcasts) at L = 5 m, with the exact polygon and
    with the thesis' Welzl-circle classification (spec: the same result with both); pass (spec
    §9.3): completes, distance to the true storm polygon >= margin - 0.5 m x5 = 22.5 m at all
    times, mission time within ±15 % of the thesis' 70 s (measured: 79.1 s / 78.5 s, closest
    29.4 m with both)."""
    data = scenario_data("reachset/s4_storm")
    data["vehicle"][0]["planner"]["options"]["constraint_mode"] = mode
    m = log_metrics(fly(data, "s4").log)["vehicles"]["quad"]
    assert m["mission"]["complete"]
    assert 70.0 * 0.85 <= m["mission"]["time_s"] <= 70.0 * 1.15
    assert m["storms"]["time_inside_s"] == 0.0
    assert m["storms"]["min_distance_m"] >= (5.0 - 0.5) * SCALE


@pytest.mark.slow  # a non-strict xfail cannot fail CI; the 10-seed batch is the measure
@pytest.mark.xfail(
    strict=False,
    reason="S8 is not met on every seed (docs/reachset.md, S8 batch table: the pairs under the "
    "line involve UAS3's slash set), and this pinned seed is one where it is not",
)
def test_four_way_head_on_s8_keeps_every_pair_apart_and_all_complete(fly):
    """S8 (four UAS meeting in the middle, non-cooperative, each with the thesis' ACAS-like set:
    UAS1/UAS4 horizontal, UAS2 vertical, UAS3 slash) at L = 5 m: pass (spec §9.3): every pair's
    minimum 3-D separation (truth, from the MCAP) above the 1.2 m line x5 and all four complete.
    One seed is a regression vector, not evidence: the 10-seed batch
    (``cosim batch scenarios/batch/s8_seeds.toml``) is the measure. A ~100 s wall-time run of
    four JSBSim quadrotors."""
    m = log_metrics(fly("reachset/s8_head_on_four").log)
    for v in ("uas1", "uas2", "uas3", "uas4"):
        assert m["vehicles"][v]["mission"]["complete"], v
    seps = {pair: s["distance_m"] for pair, s in m["separation"].items()}
    assert len(seps) == 6
    assert min(seps.values()) > SEPARATION_LINE_M, seps
