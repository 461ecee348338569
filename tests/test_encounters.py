"""Encounter campaigns: sampling, encounter construction through the sampled CPA (open loop and
flown unmitigated), the statistics against hand-computed values, and a CI-sized campaign whose
outcomes are checked against hand-computed geometry."""

from __future__ import annotations

import csv
import json
import math
import textwrap
from pathlib import Path

import numpy as np
import pytest

from sim.encounters.aggregate import Pair, ratio_interval, summarise, wilson
from sim.encounters.campaign import keep_logs, load_campaign, outcome, run_campaign
from sim.encounters.geometry import (
    MODES,
    RUN_ON_S,
    EncounterSetup,
    build_scenario,
    legs,
    second_intruder,
    start_within,
)
from sim.encounters.model import PARAMETERS, CampaignError, Distribution, parse_distributions, sample
from sim.replay.metrics import flatten
from sim.replay.runlog import RunLog
from sim.runner import run_scenario
from sim.scenario import parse_scenario

BASE = {k: d for k, (_, d, _) in PARAMETERS.items()}
SETUP = EncounterSetup(
    {"aircraft": "quadrotor", "planner": {"type": "geometric", "rate_hz": 10}},
    {"kind": "object", "radius": 0.5},
    metrics={"nmac_horizontal": 5.0, "nmac_vertical": 2.5},
)


def linear_cpa(p: dict) -> tuple[float, float, float]:
    """Horizontal CPA of the two legs by hand: time [s], horizontal miss [m], vertical miss [m]."""
    own, intr = legs(p, SETUP)
    r0, vr = intr.start - own.start, intr.velocity - own.velocity
    t = -float(r0[:2] @ vr[:2]) / float(vr[:2] @ vr[:2])
    r = r0 + vr * t
    return t, float(np.hypot(r[0], r[1])), float(-r[2])


def test_distributions_and_latin_hypercube_strata():
    d = parse_distributions(
        {
            "hmd": {"uniform": [0, 50]},
            "vmd": {"normal": [0, 3]},
            "approach_angle": {"choice": [90, 180]},
            "own_speed": 4,
        },
        "c",
    )
    draws = sample(d, 40, seed=3, latin_hypercube=True)
    hmd = np.array([x["hmd"] for x in draws])
    assert sorted(np.floor(hmd / 50 * 40).astype(int)) == list(range(40))  # one draw per stratum
    assert {x["approach_angle"] for x in draws} == {90.0, 180.0} and all(x["own_speed"] == 4.0 for x in draws)
    assert all(x["time_to_cpa"] == PARAMETERS["time_to_cpa"][1] for x in draws)  # defaults fixed
    vmd = np.array([x["vmd"] for x in draws])
    assert abs(vmd.mean()) < 0.5 and 2.0 < vmd.std() < 4.0
    assert sample(d, 40, 3, True) == draws and sample(d, 40, 4, True) != draws
    iid = np.array([x["hmd"] for x in sample(d, 40, 3)])
    assert len(set(np.floor(iid / 50 * 40).astype(int))) < 40  # independent draws leave strata empty
    assert Distribution.parse({"normal": [1.0, 0.0]}, "x").quantile(np.array([0.3])) == pytest.approx([1.0])


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ({"hmdx": 1}, "hmdx: unknown parameter"),
        ({"hmd": {"triangular": [0, 1]}}, "unknown distribution"),
        ({"hmd": {"uniform": [5, 1]}}, "lo <= hi"),
        ({"hmd": {"normal": [0]}}, "needs 2 value"),
        ({"hmd": {"choice": []}}, "at least one"),
    ],
)
def test_bad_distributions_name_the_parameter(table, message):
    with pytest.raises(CampaignError, match=message):
        parse_distributions(table, "c")


@pytest.mark.parametrize(
    ("angle", "hmd", "vmd", "vi", "vz_o", "vz_i"),
    [
        (180, 0, 0, 5, 0, 0),
        (90, 10, 0, 3, 0, 0),
        (45, -8, 3, 4, 0.5, -0.5),
        (270, 20, -2, 2, 0, 1),
        (10, 5, 0, 9, 0, 0),
    ],
)
def test_legs_pass_through_the_sampled_cpa(angle, hmd, vmd, vi, vz_o, vz_i):
    p = BASE | {
        "approach_angle": angle,
        "hmd": hmd,
        "vmd": vmd,
        "intruder_speed": vi,
        "own_vertical_rate": vz_o,
        "intruder_vertical_rate": vz_i,
        "own_heading": 30.0,
        "time_to_cpa": 12.0,
    }
    t, h, v = linear_cpa(p)
    assert t == pytest.approx(12.0) and h == pytest.approx(abs(hmd), abs=1e-9) and v == pytest.approx(vmd, abs=1e-9)
    own, _ = legs(p, SETUP)
    np.testing.assert_allclose(own.at(12.0), [0, 0, -(SETUP.altitude - SETUP.origin["altitude"])], atol=1e-9)


TRIPLE = EncounterSetup(
    {"aircraft": "quadrotor", "planner": {"type": "reachset"}},
    {"kind": "cooperative", "count": 2},
    metrics={"nmac_horizontal": 5.0, "nmac_vertical": 2.5},
)


@pytest.mark.parametrize(("angle2", "hmd2"), [(240.0, 0.0), (200.0, 6.0), (300.0, -4.0)])
def test_triple_second_intruder_passes_its_sampled_cpa_with_the_ownship(angle2, hmd2):
    """Triples: the second intruder meets the ownship at the sampled time with its own sampled
    miss (hand-computed CPA of the legs); all three vehicles fly the planner mitigated and
    ``follow_mission`` unmitigated; with both misses zero all three meet in one point."""
    p = BASE | {"approach_angle": 120.0, "approach_angle_2": angle2, "hmd_2": hmd2, "time_to_cpa": 12.0}
    p["intruder_speed_2"] = 3.5
    own, second = legs(second_intruder(p), TRIPLE)
    assert float(np.hypot(*second.velocity[:2])) == pytest.approx(3.5)
    r0, vr = second.start - own.start, second.velocity - own.velocity
    t = -float(r0[:2] @ vr[:2]) / float(vr[:2] @ vr[:2])
    assert t == pytest.approx(12.0) and float(np.hypot(*(r0 + vr * t)[:2])) == pytest.approx(abs(hmd2), abs=1e-9)
    assert np.degrees(np.arctan2(second.velocity[1], second.velocity[0])) % 360 == pytest.approx(angle2 % 360)
    scen = build_scenario(p, TRIPLE, 3, "mitigated", "tri")
    assert [v["name"] for v in scen["vehicle"]] == ["own", "intruder", "intruder2"]
    assert all(v["planner"] == {"type": "reachset"} for v in scen["vehicle"])
    unm = build_scenario(p, TRIPLE, 3, "unmitigated", "tri")
    assert all(v["planner"] == {"type": "follow_mission"} for v in unm["vehicle"])
    if hmd2 == 0.0:
        _, first = legs(p, TRIPLE)
        np.testing.assert_allclose(first.at(12.0), own.at(12.0), atol=1e-9)
        np.testing.assert_allclose(second.at(12.0), own.at(12.0), atol=1e-9)


def test_triple_outcome_is_the_closest_pair_and_any_pair_nmac():
    """A triple's run: separation fields of its closest pair (here the two intruders), NMAC and
    loss of well clear when any pair has one, complete only when all three are."""
    row = {"status": "ok"}
    for pair, h, nmac in (
        ("own-intruder", 30.0, False),
        ("own-intruder2", 12.0, False),
        ("intruder-intruder2", 3.0, True),
    ):
        row |= {f"metric.separation.{pair}.min_horizontal_m": h, f"metric.separation.{pair}.nmac": nmac}
        row |= {f"metric.separation.{pair}.lowc": pair == "own-intruder"}
    for v in ("own", "intruder", "intruder2"):
        row[f"metric.vehicles.{v}.mission.complete"] = v != "intruder2"
    o = outcome(row, "cooperative", 2)
    assert o["min_horizontal_m"] == 3.0 and o["nmac"] and o["lowc"] and not o["complete"]
    pair = outcome(row, "cooperative", 1)  # the pair campaign reads own-intruder only
    assert pair["min_horizontal_m"] == 30.0 and not pair["nmac"] and pair["lowc"] and pair["complete"]


def test_same_velocities_have_no_cpa():
    with pytest.raises(CampaignError, match="no closest approach"):
        legs(BASE | {"approach_angle": 0.0}, SETUP)


@pytest.mark.parametrize("kind", ["object", "quadrotor"])
@pytest.mark.parametrize(("estimator", "tol_h", "tol_v"), [("perfect", 1.0, 0.5), ("ekf", 2.0, None)])
def test_flown_unmitigated_cpa_is_the_sampled_one(kind, estimator, tol_h, tol_v, tmp_path):
    """JSBSim quadrotor(s) on follow_mission: the horizontal CPA at the sampled miss, the vertical
    separation there at the sampled one, at the sampled time within 1 s. Perfect navigation: within
    1 m / 0.5 m (the multirotor's ~0.35 s lag behind its carrot, ~0.5 m track wobble). On the EKF
    the horizontal miss within 2 m; the vertical one carries each vehicle's EKF altitude error
    (1.5-2 m with this seed, the same in both modes of an encounter), so it is not checked."""
    own = SETUP.ownship | {"estimator": estimator}
    setup = EncounterSetup(own, {"kind": kind, "radius": 0.5, "estimator": estimator}, after_cpa=3.0, slack=2.0)
    p = BASE | {"approach_angle": 135.0, "hmd": 6.0, "vmd": 1.5, "intruder_speed": 4.0, "time_to_cpa": 8.0}
    scen = build_scenario(p, setup, 5, "unmitigated", "cpa")
    assert all(v["planner"]["type"] == "follow_mission" for v in scen["vehicle"])
    f = flatten(run_scenario(parse_scenario(scen), tmp_path / "cpa.mcap").metrics)
    key = "vehicles.own.clearance.object.intruder" if kind == "object" else "separation.own-intruder"
    assert f[f"{key}.min_horizontal_m"] == pytest.approx(6.0, abs=tol_h)
    if tol_v is not None:
        assert f[f"{key}.vertical_at_min_horizontal_m"] == pytest.approx(1.5, abs=tol_v)
    assert f[f"{key}.t"] == pytest.approx(8.0, abs=1.0)


def test_a_non_cooperative_intruder_flies_on_along_its_leg_past_the_runs_end(tmp_path):
    """Finding 13 of docs/encounters.md: an intruder whose mission ended past the CPA hovered at its
    end point, on or beside the ownship's route. Its waypoint now lies RUN_ON_S past the run's
    end: at the end (t = 6 + 2 + 6 = 14 s) the JSBSim quadrotor is on its leg at the leg's 14 s
    point (within its ~0.35 s carrot lag, 1.4 m at 4 m/s) and it never slowed below 90 % of its
    4 m/s after the first second. A cooperative intruder keeps its goal after_cpa past the CPA
    (its mission completion counts). The run ends when the missions that count are complete: the
    ownship's (t ~ 8 s), not the intruder's."""
    own = SETUP.ownship | {"estimator": "perfect"}
    setup = EncounterSetup(own, {"kind": "quadrotor", "estimator": "perfect"}, after_cpa=2.0, slack=6.0)
    p = BASE | {"approach_angle": 90.0, "hmd": 20.0, "intruder_speed": 4.0, "time_to_cpa": 6.0}
    scen = build_scenario(p, setup, 5, "unmitigated", "run_on")
    _, leg = legs(p, setup)
    assert scen["duration"] == 14.0
    wp = scen["vehicle"][1]["mission"]["waypoints"][0]
    assert [wp["north"], wp["east"]] == pytest.approx(leg.at(14.0 + RUN_ON_S)[:2])
    coop = build_scenario(
        p, EncounterSetup(own, {"kind": "cooperative"}, after_cpa=2.0, slack=6.0), 5, "mitigated", "c"
    )
    goal = coop["vehicle"][1]["mission"]["waypoints"][0]
    assert [goal["north"], goal["east"]] == pytest.approx(leg.at(8.0)[:2])
    assert scen["stop_when_complete"] == ["own"] and coop["stop_when_complete"] == ["own", "intruder"]
    res = run_scenario(parse_scenario(scen), tmp_path / "ends.mcap")
    assert res.status == "completed" and res.sim_time_s < 9.0
    assert res.missions["own"].complete and not res.missions["intruder"].complete
    run_scenario(parse_scenario(scen | {"stop_when_complete": False}), tmp_path / "run_on.mcap")
    st = RunLog(tmp_path / "run_on.mcap").topic("/intruder/truth/state")
    pos, vel = np.asarray(st["pos_ned"]), np.asarray(st["vel_ned"])
    u = leg.velocity[:2] / np.linalg.norm(leg.velocity[:2])
    off = pos[-1, :2] - leg.at(float(st.t[-1]))[:2]
    assert st.t[-1] == pytest.approx(14.0, abs=0.1)
    assert abs(off[0] * u[1] - off[1] * u[0]) < 0.5 and -1.6 < off @ u < 0.5  # on the leg, lagging
    assert np.hypot(vel[st.t > 1.0, 0], vel[st.t > 1.0, 1]).min() > 0.9 * 4.0


def test_wilson_and_ratio_interval_by_hand():
    lo, hi = wilson(0, 20)
    assert lo == 0.0 and hi == pytest.approx(1.959964**2 / (20 + 1.959964**2), rel=1e-6)  # 0.1611
    assert wilson(10, 20) == pytest.approx((0.299298, 0.700702), abs=1e-6)
    # zero mitigated NMACs: the upper limit is u1 / sqrt(l2 (2 p2 - l2)) (MOVER-R)
    l2 = wilson(10, 20)[0]
    assert ratio_interval(0, 20, 10, 20) == pytest.approx((0.0, hi / math.sqrt(l2 * (1.0 - l2))), rel=1e-9)
    lo, hi = ratio_interval(7, 20, 7, 20)
    assert lo < 1.0 < hi
    assert ratio_interval(3, 20, 0, 20) is None


def test_summary_counts_induced_nmacs_and_ratios():
    g = {"approach": "180 head-on"}
    pairs = [Pair(False, True, True, True, True, g)] * 6 + [Pair(True, False, True, False, False, g)]
    pairs += [Pair(False, False, False, True, True, g)] * 3
    s = summarise(pairs)
    assert s["n"] == 10 and s["nmac_mitigated"] == 1 and s["nmac_unmitigated"] == 6 and s["induced_nmac"] == 1
    assert s["risk_ratio"] == pytest.approx(1 / 6) and s["lowc_ratio"] == pytest.approx(7 / 9)
    assert s["completion_rate"] == pytest.approx(0.9)
    assert s["risk_ratio_ci95"][0] < 1 / 6 < s["risk_ratio_ci95"][1]


CI_ENCOUNTERS = 8  # encounters of CAMPAIGN flown, each in both modes, by the CI campaign test
CAMPAIGN = """
name = "ci"
seed = 5
encounters = 20
after_cpa = 4
slack = 6
surveillance_rate_hz = 10
[ownship]
aircraft = "quadrotor"
acceptance_radius = 2
planner = { type = "geometric", rate_hz = 10, options = { conflict_horizon_s = 2.0 } }
[intruder]
kind = "object"
radius = 0.5
[parameters]
approach_angle = { choice = [180, 180, 90] }
hmd = { choice = [0, 500] }
time_to_cpa = 6
intruder_speed = 3
surveillance_noise_h = 0.3
surveillance_noise_v = 0.3
surveillance_latency = 0.1
surveillance_dropout = 0.0
"""


def test_ci_campaign_outcomes_match_hand_computed_geometry(tmp_path):
    """8 encounters, head-on/crossing with a zero or 500 m miss against a scripted 0.5 m sphere:
    unmitigated, a zero miss is an NMAC (5 m / 2.5 m cylinder) and 500 m is not, both lose well
    clear (2000 ft / 250 ft); counts, outputs, kept logs and resume."""
    path = _campaign_file(tmp_path, **{"encounters = 20": f"encounters = {CI_ENCOUNTERS}"})
    out = tmp_path / "out"
    c = load_campaign(path, out)
    assert len(c.runs) == 2 * CI_ENCOUNTERS and c.planner == "geometric"
    summary = run_campaign(c, out, workers=2)["geometric"]
    with open(out / "encounters.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 2 * CI_ENCOUNTERS and {r["mode"] for r in rows} == {"mitigated", "unmitigated"}
    unm = [r for r in rows if r["mode"] == "unmitigated"]
    zero = [r for r in unm if float(r["hmd"]) == 0.0]
    assert zero and len(zero) < CI_ENCOUNTERS
    for r in unm:
        assert (r["nmac"] == "True") == (float(r["hmd"]) == 0.0), r
        assert r["lowc"] == "True", r  # 500 m is inside the 2000 ft (609.6 m) well-clear radius
    mit = [r for r in rows if r["mode"] == "mitigated"]
    assert summary["n"] == CI_ENCOUNTERS and summary["nmac_unmitigated"] == len(zero)
    assert summary["nmac_mitigated"] == sum(r["nmac"] == "True" for r in mit)
    assert summary["risk_ratio"] == pytest.approx(summary["nmac_mitigated"] / len(zero))
    # a mitigated run that touches the sphere crashes (sim/contacts.py) and so does not complete
    crashed = [r for r in mit if r["status"] == "crashed"]
    assert all(r["nmac"] == "True" for r in crashed)
    assert summary["induced_nmac"] == 0 and summary["completion_rate"] == 1.0 - len(crashed) / CI_ENCOUNTERS
    assert json.loads((out / "summary.json").read_text())["geometric"]["n"] == CI_ENCOUNTERS
    assert "risk_ratio" in (out / "report.md").read_text() and (out / "separation.png").is_file()
    kept = {r["mcap"] for r in rows if r["mcap"]}
    assert all((out / k).is_file() for k in kept) and len(list((out / "runs").glob("*.mcap"))) == len(kept)
    flown = []
    run_campaign(c, out, workers=1, progress=lambda k, n, row: flown.append(row))
    assert flown == []  # resumed: nothing re-flown


def _campaign_file(tmp_path, text: str = CAMPAIGN, **replace: str):
    body = textwrap.dedent(text)
    for old, new in replace.items():
        body = body.replace(old, new)
    path = tmp_path / "c.toml"
    path.write_text(body)
    return path


def test_limit_takes_the_first_draws_and_slow_closing_draws_are_skipped(tmp_path):
    full = load_campaign(_campaign_file(tmp_path), tmp_path / "o")
    part = load_campaign(_campaign_file(tmp_path), tmp_path / "o", limit=5)
    assert [r.run_id for r in part.runs] == [r.run_id for r in full.runs[:10]]
    assert [r.scenario for r in part.runs] == [r.scenario for r in full.runs[:10]]
    picked = load_campaign(_campaign_file(tmp_path), tmp_path / "o", draws=[3, 1, 3])
    assert [r.run_id for r in picked.runs] == [r.run_id for r in full.runs[2:4] + full.runs[6:8]]
    assert [r.scenario for r in picked.runs] == [r.scenario for r in full.runs[2:4] + full.runs[6:8]]
    with pytest.raises(CampaignError, match=r"draw 20: out of range 0\.\.19"):
        load_campaign(_campaign_file(tmp_path), tmp_path / "o", draws=[2, 20])
    # overtaking at equal speed: no closing speed, every draw skipped (and counted)
    same = _campaign_file(
        tmp_path,
        **{
            "approach_angle = { choice = [180, 180, 90] }": "approach_angle = 0",
            "intruder_speed = 3": "intruder_speed = 5",
        },
    )
    with pytest.raises(CampaignError, match="no encounter closes"):
        load_campaign(same, tmp_path / "o")
    slow = _campaign_file(
        tmp_path,
        **{
            "approach_angle = { choice = [180, 180, 90] }": "approach_angle = { choice = [0, 180] }",
            "intruder_speed = 3": "intruder_speed = 5",
        },
    )
    c = load_campaign(slow, tmp_path / "o")
    assert c.skipped > 0 and len(c.encounters) + c.skipped == 20
    assert all(e.params["approach_angle"] == 180.0 for e in c.encounters)


def test_draws_starting_inside_the_nmac_cylinder_and_start_margin_are_skipped(tmp_path):
    # head-on at 5 + 3 m/s with no miss: 0.8 s before the CPA the two start 6.4 m apart, inside the
    # 5 m cylinder + the default 2.5 m margin (skipped), outside it with start_margin = 1 (flown);
    # 6 s before, 48 m apart (flown). Draw 367 of geometric_quad_pairs (6.9 m) is one of these.
    text = {
        "approach_angle = { choice = [180, 180, 90] }": "approach_angle = 180",
        "hmd = { choice = [0, 500] }": "hmd = 0",
        "time_to_cpa = 6": "time_to_cpa = { choice = [0.8, 6] }",
    }
    c = load_campaign(_campaign_file(tmp_path, **text), tmp_path / "o")
    assert {e.params["time_to_cpa"] for e in c.encounters} == {6.0} and c.skipped > 0
    assert len(c.encounters) + c.skipped == 20
    wide = load_campaign(_campaign_file(tmp_path, **text, **{"seed = 5": "seed = 5\nstart_margin = 1"}), tmp_path / "o")
    assert wide.skipped == 0 and len(wide.encounters) == 20
    assert start_within(BASE | {"time_to_cpa": 0.8, "intruder_speed": 3.0}, SETUP, 5.0 + 2.5, 2.5 + 2.5)
    assert not start_within(BASE | {"time_to_cpa": 0.8, "intruder_speed": 3.0}, SETUP, 5.0 + 1.0, 2.5 + 1.0)
    assert not start_within(BASE | {"time_to_cpa": 0.8, "intruder_speed": 3.0, "vmd": 6.0}, SETUP, 7.5, 5.0)


@pytest.mark.parametrize(("keep_below", "kept_encounters"), [(None, set()), (40, {0, 2})])
def test_keep_below_m_keeps_the_logs_of_a_breached_margin(tmp_path, keep_below, kept_encounters):
    """A mitigated run passing closer than ``keep_below_m`` (horizontal) keeps both runs of its
    encounter, without NMAC or failure (a rules campaign's breached case margin); a close
    unmitigated run alone keeps nothing; a 0 m pass counts."""
    extra = "" if keep_below is None else f"\nkeep_below_m = {keep_below}"
    c = load_campaign(_campaign_file(tmp_path, **{"seed = 5": "seed = 5" + extra}), tmp_path / "o", limit=4)
    assert len(c.encounters) == 4 and c.modes == ("mitigated", "unmitigated")
    mitigated_min = [30.0, 45.0, 0.0, 60.0]
    table = [
        {"status": "completed", "nmac": False, "complete": True, "min_horizontal_m": h}
        for m in mitigated_min
        for h in (m, 10.0)  # mitigated, then a close unmitigated run
    ]
    runs = {spec.run_id: spec.params["encounter"] for spec in c.runs}
    indices = [e.index for e in c.encounters]
    assert {runs[r] for r in keep_logs(c, table)} == {indices[k] for k in kept_encounters}
    assert len(keep_logs(c, table)) == 2 * len(kept_encounters)


@pytest.mark.parametrize(
    ("replace", "message"),
    [
        ({'kind = "object"': 'kind = "blimp"'}, "intruder.kind: one of"),
        ({"encounters = 20": "encounters = 0"}, "encounters: a positive integer"),
        ({"seed = 5": "seed = 5\nfoo = 1"}, "foo: unknown key"),
        ({"hmd = { choice = [0, 500] }": "hmd = { choice = [0, 500] }\nspeed = 3"}, "speed: unknown parameter"),
        ({'type = "geometric"': 'type = "warp"'}, "planner.type"),
        ({"radius = 0.5": "radius = 0.5\ncount = 2"}, "intruder.count: 1, or 2 for kind 'cooperative'"),
        ({'kind = "object"': 'kind = "cooperative"\ncount = 3'}, "intruder.count"),
        ({"seed = 5": "seed = 5\nstart_margin = -1"}, "start_margin: a distance >= 0"),
        ({"seed = 5": "seed = 5\nkeep_below_m = -1"}, "keep_below_m: a distance >= 0"),
        ({"seed = 5": 'seed = 5\nkeep_below_m = "40"'}, "keep_below_m: a distance >= 0"),
        ({"surveillance_dropout = 0.0": "surveillance_dropout = 0.0\n[metrics]\nnmac_horizontal = -5"}, "metrics: "),
    ],
)
def test_bad_campaign_files_are_one_line_errors(tmp_path, replace, message):
    with pytest.raises(CampaignError, match=message) as err:
        load_campaign(_campaign_file(tmp_path, **replace), tmp_path / "o")
    assert "\n" not in str(err.value)


@pytest.mark.closed_loop
def test_campaign_same_outputs_on_process_pool_and_dask(tmp_path):
    distributed = pytest.importorskip("distributed")
    path = _campaign_file(tmp_path, **{"encounters = 20": "encounters = 2"})
    pool = run_campaign(load_campaign(path, tmp_path / "pool"), tmp_path / "pool", workers=2)
    with (
        distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster,
        distributed.Client(cluster) as client,
    ):
        dask = run_campaign(load_campaign(path, tmp_path / "dask"), tmp_path / "dask", executor=client.get_executor())
    assert pool == dask

    def table(folder: str) -> list[dict]:
        with open(tmp_path / folder / "encounters.csv") as f:
            return [{k: v for k, v in r.items() if k != "latency_p95_ms"} for r in csv.DictReader(f)]  # wall clock

    assert table("pool") == table("dask") and len(table("pool")) == 4


def test_every_parameter_and_setup_field_reaches_the_scenario():
    """Sensor quality, wind, planners per mode and intruder kind, initial overrides, NMAC metrics."""
    p = BASE | {
        "surveillance_noise_h": 1.5,
        "surveillance_noise_v": 2.5,
        "surveillance_latency": 0.3,
        "surveillance_dropout": 0.1,
        "wind_speed": 4.0,
        "wind_direction": 90.0,
        "own_speed": 4.0,
        "own_vertical_rate": 1.0,
    }
    coop = EncounterSetup(
        {"aircraft": "quadrotor", "planner": {"type": "geometric"}, "estimator": "perfect"},
        {"kind": "cooperative", "initial": {"roll": 1.0}},
        surveillance_rate_hz=5.0,
        metrics={"nmac_horizontal": 7.0},
    )
    s = build_scenario(p, coop, 9, "mitigated", "x")
    assert s["surveillance"] == {
        "rate_hz": 5.0,
        "latency": 0.3,
        "dropout": 0.1,
        "position_noise_horizontal": 1.5,
        "position_noise_vertical": 2.5,
    }
    assert s["wind"]["north"] == pytest.approx(0.0, abs=1e-12) and s["wind"]["east"] == pytest.approx(4.0)
    own, intr = s["vehicle"]
    assert own["planner"] == intr["planner"] == {"type": "geometric"} and own["estimator"] == "perfect"
    assert intr["initial"]["roll"] == 1.0 and s["metrics"] == {"nmac_horizontal": 7.0} and s["seed"] == 9
    assert own["mission"]["cruise_speed"] == pytest.approx(math.hypot(4.0, 1.0))  # 3-D leg speed
    assert own["initial"]["airspeed"] == pytest.approx(4.0)
    unm = build_scenario(p, coop, 9, "unmitigated", "x")
    assert [v["planner"] for v in unm["vehicle"]] == [{"type": "follow_mission"}] * 2
    haps = build_scenario(p, EncounterSetup(coop.ownship, {"kind": "haps"}), 9, "mitigated", "x")
    assert haps["vehicle"][1]["aircraft"] == "haps" and haps["vehicle"][1]["planner"] == {"type": "follow_mission"}
    with pytest.raises(ValueError, match="mode must be one of"):
        build_scenario(p, coop, 9, "both", "x")


@pytest.mark.closed_loop
def test_ci_cooperative_triple_keeps_the_roundabout_margin_where_unmitigated_they_meet(tmp_path):
    """CI-sized scenarios/encounters/rules_cooperative_triples.toml (its first draw: intruders at
    108° and 240°, misses 3.1 m and 6.7 m, 31 s run-in). Unmitigated, every pair's closest
    approach is the hand-computed one of the straight legs (within 1.5 m: multirotor tracking on
    the EKF); under the rules of the air every pair keeps the 50 m head-on / roundabout margin and
    all three complete."""
    path = Path(__file__).resolve().parents[1] / "scenarios" / "encounters" / "rules_cooperative_triples.toml"
    c = load_campaign(path, tmp_path, limit=1)
    (enc,) = c.encounters
    run_campaign(c, tmp_path, workers=1)
    own, first = legs(enc.params, c.setup)
    _, second = legs(second_intruder(enc.params), c.setup)

    def miss(a, b) -> float:
        r0, vr = b.start - a.start, b.velocity - a.velocity
        return float(np.hypot(*(r0 - vr * float(r0[:2] @ vr[:2]) / float(vr[:2] @ vr[:2]))[:2]))

    hand = {
        "own-intruder": miss(own, first),
        "own-intruder2": miss(own, second),
        "intruder-intruder2": miss(first, second),
    }
    flown = {m: json.loads((tmp_path / "runs" / f"{c.name}_00000_{m}.json").read_text()) for m in MODES}
    for pair, h in hand.items():
        assert flown["unmitigated"][f"metric.separation.{pair}.min_horizontal_m"] == pytest.approx(h, abs=1.5), pair
        assert flown["mitigated"][f"metric.separation.{pair}.min_horizontal_m"] >= 50.0, pair
    assert all(flown["mitigated"][f"metric.vehicles.{v}.mission.complete"] for v in ("own", "intruder", "intruder2"))


def test_cli_draws_option_parses_indices_and_excludes_limit(capsys):
    from sim.cli import build_parser

    parser = build_parser()
    assert parser.parse_args(["encounters", "c.toml", "--draws", "59,144"]).draws == [59, 144]
    for bad in (["--draws", "1,x"], ["--draws", "1", "--limit", "3"]):
        with pytest.raises(SystemExit):
            parser.parse_args(["encounters", "c.toml", *bad])
    assert "--draws" in capsys.readouterr().err
