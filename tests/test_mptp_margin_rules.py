"""MPTP margins by Table 3.1, by cell area and by wind side, and probability levels (seed 002,
3.1.1 end and 3.1.2), on hand-checkable geometry.

Margin polygons are convex hulls of circumscribed 16-gons at the cell's vertices, so the margin
beyond a cell's side lies between r and r / cos(pi / 16) (the 16-gon's apothem and corner).
"""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from shapely.geometry import box

from guidance.mptp.config import NM, MptpConfig
from guidance.mptp.margins import CIRCLE_SEGMENTS, margin_hulls, safety_margin_m
from guidance.mptp.planner import MptpPlanner
from guidance.mptp.timeline import ObstacleTimeline
from sim.core.mission import Mission
from sim.core.plan import PlanStatus, Threats
from sim.core.threats import StormSnapshot
from sim.testbeds.mptp_openloop import vehicle_state

CORNER = 1.0 / math.cos(math.pi / CIRCLE_SEGMENTS)  # 16-gon corner / apothem
TABLE_3_1 = MptpConfig(  # Table 3.1 [NM]; its wind-speed bands applied to the cell's speed
    safety_single_m=(20 * NM, 25 * NM, 30 * NM),
    safety_line_m=(30 * NM, 35 * NM, 40 * NM),
    sigma_front_mps=0.0,
    sigma_back_mps=0.0,
)


def _extents(cell, hull) -> dict[str, float]:
    """How far the hull reaches beyond the cell's box to the north, south, east, west [m]."""
    (cn0, ce0, cn1, ce1), (hn0, he0, hn1, he1) = cell.bounds, hull.bounds
    return {"north": hn1 - cn1, "south": cn0 - hn0, "east": he1 - ce1, "west": ce0 - he0}


@pytest.mark.parametrize(
    ("speed", "single_nm", "line_nm"),
    [(0.0, 20, 30), (9.99, 20, 30), (10.0, 25, 35), (15.0, 25, 35), (19.99, 25, 35), (20.0, 30, 40), (35.0, 30, 40)],
)
def test_table_3_1_safety_margins_by_speed_band_and_appearance(speed, single_nm, line_nm):
    got = safety_margin_m(np.array([speed, speed]), np.array([False, True]), TABLE_3_1)
    np.testing.assert_allclose(got, [single_nm * NM, line_nm * NM])
    # the margin polygon of a 2 km square (single) and a 40 x 2 km bar (line) moving east
    for cell, nm in ((box(0, 0, 2000, 2000), single_nm), (box(0, 0, 2000, 40_000), line_nm)):
        hull = margin_hulls([cell], np.array([[0.0, speed]]), 0.0, TABLE_3_1)[0]
        for reach in _extents(cell, hull).values():
            assert nm * NM - 1e-6 <= reach <= nm * NM * CORNER + 1e-6


def test_safety_margin_grows_by_the_area_step_of_the_cell():
    cfg = TABLE_3_1.with_(safety_area_steps=((100.0, 2000.0), (400.0, 5000.0)))
    areas_km2 = np.array([50.0, 99.9, 100.0, 399.0, 400.0, 2500.0])
    got = safety_margin_m(np.zeros(6), np.zeros(6, bool), cfg, areas_km2 * 1e6)
    np.testing.assert_allclose(got, 20 * NM + np.array([0, 0, 2000, 2000, 5000, 5000]))
    small, large = box(0, 0, 5000, 5000), box(0, 0, 25_000, 25_000)  # 25 and 625 km^2
    h_small, h_large = margin_hulls([small, large], np.zeros((2, 2)), 0.0, cfg)
    assert _extents(small, h_small)["north"] == pytest.approx(20 * NM * CORNER)
    assert _extents(large, h_large)["north"] == pytest.approx((20 * NM + 5000.0) * CORNER)
    # the steps off: the same cells get the same margin
    _, h_plain = margin_hulls([small, large], np.zeros((2, 2)), 0.0, TABLE_3_1)
    assert _extents(large, h_plain)["north"] == pytest.approx(20 * NM * CORNER)


def test_downwind_margin_is_the_factor_times_the_upwind_one():
    """Wind towards east, factor 2: around each corner of a static square the safety reach in
    direction phi off downwind is 5 km (1 + (1 + cos phi) / 2), 10 km east and 5 km west; the
    16-gon has corners every 22.5 deg, each at its reach / cos(pi / 16). North and south the
    hull's reach is the 16-gon corner at phi = 67.5 deg: 5 km (1 + (1 + cos 67.5)/2) sin 67.5."""
    cfg = MptpConfig(safety_single_m=(5000.0,) * 3, sigma_front_mps=0.0, sigma_back_mps=0.0, downwind_factor=2.0)
    cell = box(0, 0, 2000, 2000)
    hull = margin_hulls([cell], np.zeros((1, 2)), 0.0, cfg, wind_ne=np.array([0.0, 10.0]))[0]
    reach = _extents(cell, hull)
    across = 5000.0 * (1.0 + 0.5 * (1.0 + math.cos(math.radians(67.5)))) * math.sin(math.radians(67.5))
    expected = {"east": 10_000.0, "west": 5_000.0, "north": across, "south": across}
    assert reach == pytest.approx({k: v * CORNER for k, v in expected.items()})
    # the planner's timeline takes its frame's drift (the wind forecast) as the wind; it adds its
    # inflation to every radius and smooths within half the tolerance
    tl = ObstacleTimeline([StormSnapshot(0.0, (cell,), np.zeros((1, 2)))], cfg, 600.0, np.array([0.0, 10.0]))
    swept = _extents(cell, tl.shape_at(0.0))
    for side, hand in (("east", 10_000.0), ("west", 5_000.0)):
        assert swept[side] == pytest.approx((hand + tl.extra_m) * CORNER, abs=0.5 * cfg.simplify_tol_m)
    # in still air the cell's motion is downwind (north here); factor 1 = symmetric
    moving = margin_hulls([cell], np.array([[5.0, 0.0]]), 0.0, cfg)[0]
    assert _extents(cell, moving)["north"] / _extents(cell, moving)["south"] == pytest.approx(2.0)
    even = margin_hulls([cell], np.zeros((1, 2)), 0.0, cfg.with_(downwind_factor=1.0), wind_ne=np.array([0.0, 10.0]))
    assert _extents(cell, even[0])["east"] == pytest.approx(_extents(cell, even[0])["west"])


# A wall of two static cells across a 40 km wide mission area with a 4 km gap on the direct
# route east; the probabilistic margin grows k(P) * 1 m/s * lead time on both sides of the gap:
# it closes at 934 m / k(P) (safety 1 km + 66 m inflation per side): 308 s at P = 0.99, 690 s at
# P = 0.6, 793 s at P = 0.5, while the aircraft (26 m/s) is in the gap from about 330 s to 550 s.
WALL = (box(-50_000, 10_000, -2000, 12_000), box(2000, 10_000, 50_000, 12_000))
AREA = ((-20_000.0, -5000.0), (-20_000.0, 30_000.0), (20_000.0, 30_000.0), (20_000.0, -5000.0))


def _gap_plan(probabilities: tuple[float, ...], probability: float = 0.9):
    cfg = MptpConfig(
        safety_single_m=(1000.0,) * 3,
        safety_line_m=(1000.0,) * 3,
        sigma_front_mps=1.0,
        sigma_back_mps=1.0,
        simplify_tol_m=50.0,
        mission_area=AREA,
        probability=probability,
        probabilities=probabilities,
        max_expansions=30,  # the closed gap is declared at the cap (a partial plan)
    )
    mission = Mission(np.array([[0.0, 25_000.0, 0.0]]), cfg.tas_mps, 500.0)
    planner = MptpPlanner(mission, cfg)
    storms = [StormSnapshot(0.0, WALL, np.zeros((2, 2)))]
    plan = planner.plan(vehicle_state(0.0, np.zeros(2), math.pi / 2, cfg.tas_mps), Threats(storms=storms), 0.0)
    return plan, planner


def test_the_plan_of_the_largest_feasible_probability_is_flown():
    single = {p: _gap_plan((), p)[0] for p in (0.99, 0.6, 0.5)}
    assert single[0.99].diagnostics["search"] != "ok"  # the gap closes before the aircraft is through
    assert single[0.6].status == PlanStatus.OK and single[0.5].status == PlanStatus.OK
    # 0.99 has no plan: the lower level's plan is flown, the same one as P = 0.6 alone
    plan, planner = _gap_plan((0.5, 0.99, 0.6))
    assert plan.status == PlanStatus.OK
    assert plan.diagnostics["probability"] == 0.6 and plan.diagnostics["levels_tried"] == 2
    np.testing.assert_allclose(plan.positions, single[0.6].positions)
    assert planner.timeline is not None and planner.timeline.cfg.probability == 0.6
    # when the higher level is feasible it is taken, never a lower one
    plan, planner = _gap_plan((0.5, 0.6))
    assert plan.diagnostics["probability"] == 0.6 and plan.diagnostics["levels_tried"] == 1
    # no level feasible: the largest P's fall-back (its margins are the ones flown)
    plan, planner = _gap_plan((0.99, 0.98))
    assert plan.status != PlanStatus.OK and plan.diagnostics["probability"] == 0.99
    assert plan.diagnostics["levels_tried"] == 2 and planner.timeline.cfg.probability == 0.99
    np.testing.assert_allclose(plan.positions, single[0.99].positions)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("probabilities", [0.5, 1.0]),
        ("safety_area_steps", [[100.0, 1000.0], [50.0, 2000.0]]),
        ("safety_area_steps", [[100.0, -1.0]]),
        ("downwind_factor", 0.9),
        ("holding_points", [1000.0, 2000.0]),
    ],
)
def test_bad_margin_and_holding_options_are_refused(field, value):
    with pytest.raises(ValueError, match=field):
        MptpConfig(**{field: value})


LEVELS_SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "mptp" / "nowcast_levels.toml"


@pytest.mark.closed_loop
@pytest.mark.slow
def test_the_nowcast_levels_scenario_is_flown_outside_every_cell(tmp_path):
    """The shipped scenario with three P levels, downwind and area margins and V_cor holding:
    the mission completes, never inside a true cell; every complete plan is of the first level
    that had one (levels_tried = its rank), and more than one level is flown over the flight."""
    from sim.replay.report import log_metrics
    from sim.replay.runlog import RunLog
    from sim.runner import run_scenario
    from sim.scenario import load_scenario

    scenario, text = load_scenario(LEVELS_SCENARIO)
    path = tmp_path / "run.mcap"
    assert run_scenario(scenario, path, scenario_text=text).status == "completed"
    log = RunLog(path)
    haps = log_metrics(log)["vehicles"]["haps"]
    assert haps["mission"]["time_s"] is not None and haps["storms"]["time_inside_s"] == 0.0
    levels = (0.99, 0.9, 0.5)
    flown = set()
    for message in log.topic("/haps/plan").messages:
        d = message["diagnostics"]
        d = json.loads(d) if isinstance(d, str) else d
        if "complete" in d:  # the mission is done
            continue
        assert d["probability"] in levels
        if "nav_sigma_m" in d:  # the first plan waits for the navigation: no level searched
            assert d["probability"] == levels[0] and d["levels_tried"] == 0
        elif d.get("search") == "ok":
            assert d["levels_tried"] == levels.index(d["probability"]) + 1
        else:
            assert d["probability"] == levels[0] and d["levels_tried"] == len(levels)
        flown.add(d["probability"])
    assert len(flown) >= 2
