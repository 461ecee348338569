"""Cooperative rules of the air in the closed loop (spec §9.3 S9-S14, scaled by 5: docs/rules.md),
JSBSim quadrotors on their EKF estimates; pass/fail numbers read back from the MCAP: pairwise
minimum separation from the replay metrics, case and rule names from the decision events."""

from pathlib import Path

import numpy as np
import pytest

from sim.replay.report import log_metrics
from sim.replay.runlog import RunLog
from sim.runner import run_scenario
from sim.scenario import load_scenario

pytestmark = pytest.mark.closed_loop

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios" / "rules"
UNIT = 5.0  # rules_unit of the scenarios: the thesis' metre [m]
HEAD_ON_MARGIN, CONVERGING_MARGIN, OVERTAKE_MARGIN = 10 * UNIT, 8 * UNIT, 5 * UNIT  # (6.192)-(6.194), [R] defaults


def fly(name: str, tmp_path, seed: int | None = None, **update) -> tuple[dict, RunLog]:
    """Fly a rules scenario (with ``seed`` in place of its own, and the scenario fields in
    ``update``, e.g. ``duration``) and read its metrics back."""
    out = tmp_path / f"{name}.mcap"
    scenario, text = load_scenario(SCENARIOS / f"{name}.toml")
    if seed is not None:
        update["seed"] = seed
    if update:
        scenario = scenario.model_copy(update=update)
    run_scenario(scenario, out, scenario_text=text)
    log = RunLog(out)
    return log_metrics(log), log


def events(log: RunLog, vehicle: str) -> list[str]:
    """Every event of the vehicle's reach-set decisions (rule events: ``rule:<code>:...``)."""
    return [e for m in log.topic(f"/{vehicle}/plan/decision").messages for e in m["events"]]


def separation(metrics: dict, a: str, b: str) -> float:
    return metrics["separation"][f"{a}-{b}"]["distance_m"]


def assert_complete(metrics: dict) -> None:
    for name, v in metrics["vehicles"].items():
        assert v["mission"]["complete"], f"{name} did not complete"


def test_s9_converging_the_uas_with_traffic_on_its_right_gives_way(tmp_path):
    m, log = fly("s9_converging", tmp_path)
    assert_complete(m)
    assert separation(m, "uas1", "uas2") >= CONVERGING_MARGIN
    e1, e2 = events(log, "uas1"), events(log, "uas2")
    assert "rule:converging:self-uas2:converging:converging" in e1  # uas1 gives way
    assert not any(e.startswith(("rule:case_unresolved", "rule:deadlock")) for e in e1 + e2)
    assert "rule:case_open:self-uas1:converging:right_of_way" in e2
    assert not any(e.startswith(("rule:converging", "rule:right_plane_heading")) for e in e2)  # holds course


def test_s10_head_on_both_turn_right(tmp_path):
    m, log = fly("s10_head_on", tmp_path)
    assert_complete(m)
    assert separation(m, "uas1", "uas2") >= HEAD_ON_MARGIN
    for me, peer in (("uas1", "uas2"), ("uas2", "uas1")):
        e = events(log, me)
        assert f"rule:head_on:self-{peer}:head_on:roundabout" in e
        assert not any(x.startswith(("rule:case_unresolved", "rule:deadlock")) for x in e)
    # uas1 flies east on north = 100 m: its right is south; uas2 flies west: its right is north
    n1 = log.topic("/uas1/truth/state")["pos_ned"][:, 0]
    n2 = log.topic("/uas2/truth/state")["pos_ned"][:, 0]
    assert n1.min() < 100.0 - UNIT and n1.max() < 100.0 + UNIT
    assert n2.max() > 100.0 + UNIT and n2.min() > 100.0 - UNIT


def test_s11_four_uas_circle_one_roundabout(tmp_path):
    m, log = fly("s11_roundabout", tmp_path)
    assert_complete(m)
    # every pair, head-on or converging, keeps the roundabout margin = the largest case margin
    assert min(x["distance_m"] for x in m["separation"].values()) >= HEAD_ON_MARGIN
    for v in ("uas1", "uas2", "uas3", "uas4"):
        assert not any(e.startswith(("rule:case_unresolved", "rule:deadlock")) for e in events(log, v))
        rbs = [r for msg in log.topic(f"/{v}/plan/rules").messages for r in msg["roundabouts"]]
        assert any(len(r["members"]) == 4 for r in rbs)
        centre = np.mean([r["centre_enu"] for r in rbs if len(r["members"]) == 4], axis=0)
        assert np.hypot(centre[0] - 100.0, centre[1] - 100.0) < 2 * UNIT  # the crossing point


def test_s11_seed_17_starts_along_its_line(tmp_path):
    """S11 seed 17, first 15 s: uas4's first estimate is 5.5 m north of it (the EKF's alignment),
    its first plan pulls it north at 2.8 m/s for a second, and the next decision must plan along
    its yaw (south), not that course: planned north, its reach sets turned it the whole way round,
    38 m east of its line, into the roundabout's quadrant where uas2 came up (22.6 m apart)."""
    _, log = fly("s11_roundabout", tmp_path, 17, duration=15.0)
    uas4 = log.topic("/uas4/truth/state")
    assert np.abs(uas4["pos_ned"][:, 1] - 100.0).max() < 8.0  # its line: east 100 m


# In CI the 4x overtake (the one the overtaken UAS's speed estimate made fail); 2x and 3x slow
@pytest.mark.parametrize(
    "name",
    [
        pytest.param("s12_overtake_2x", marks=pytest.mark.slow),
        pytest.param("s13_overtake_3x", marks=pytest.mark.slow),
        "s13_overtake_4x",
    ],
)
def test_s12_s13_overtake_on_the_right(name, tmp_path):
    m, log = fly(name, tmp_path)
    assert_complete(m)
    assert separation(m, "uas1", "uas2") >= OVERTAKE_MARGIN
    e1 = events(log, "uas1")
    assert "rule:overtake:self-uas2:overtake:overtaking" in e1
    assert any(e.startswith("rule:overtake_waypoint:self-uas2:") for e in e1)
    assert not any(e.startswith("rule:overtake_speed") for e in e1)  # one overtake: 6.202 does not act
    # abeam (east positions equal), the overtaking uas1 is south of uas2: on its right
    s1, s2 = log.topic("/uas1/truth/state"), log.topic("/uas2/truth/state")
    p1, p2 = s1["pos_ned"], s2["pos_ned"][np.searchsorted(s2.t, s1.t).clip(max=len(s2.t) - 1)]
    k = int(np.flatnonzero(np.diff(np.sign(p1[:, 1] - p2[:, 1])) > 0)[0])
    assert p2[k, 0] - p1[k, 0] >= OVERTAKE_MARGIN


def test_s14_adversarial_pursuer_is_reported_unresolved(tmp_path):
    """Negative test: a UAS that broadcasts like a cooperative one but flies at uas1 breaks the
    head-on margin; uas1 reports the case as unresolved (not hidden) at a time the logged truth
    confirms the breach, while the cooperative pair uas1-uas2 keeps its margin."""
    m, log = fly("s14_pursuer", tmp_path)
    assert m["vehicles"]["uas2"]["mission"]["complete"]  # uas1 is being chased: no completion asked
    assert separation(m, "uas1", "uas2") >= HEAD_ON_MARGIN
    assert separation(m, "uas1", "uas3") < HEAD_ON_MARGIN  # the pursuer got through
    dec = log.topic("/uas1/plan/decision")
    reported = [
        t
        for t, msg in zip(dec.t, dec.messages, strict=False)
        if any(e.startswith("rule:case_unresolved:self-uas3:") for e in msg["events"])
    ]
    assert reported
    assert not any(e.startswith("rule:case_unresolved:self-uas2:") for e in events(log, "uas1"))
    p1, p3 = log.topic("/uas1/truth/state"), log.topic("/uas3/truth/state")
    k1, k3 = np.searchsorted(p1.t, reported[0]), np.searchsorted(p3.t, reported[0])
    true_sep = np.linalg.norm(p1["pos_ned"][k1] - p3["pos_ned"][k3])
    assert true_sep < HEAD_ON_MARGIN + 2 * UNIT  # reported when it happened (track noise, one frame)


def test_mixed_haps_and_multirotor_swarm_the_quadrotors_give_way(tmp_path):
    """The HAPS (filed as linear-propulsion, above VTOL) crosses three quadrotors in one altitude
    band: each quadrotor takes the give-way role against it and keeps the converging margin."""
    m, log = fly("mixed_haps_swarm", tmp_path)
    assert_complete(m)
    for q in ("quad1", "quad2", "quad3"):
        assert separation(m, "haps", q) >= CONVERGING_MARGIN, q
        assert "rule:case_open:self-haps:converging:converging" in events(log, q), q  # gives way
    haps = log.topic("/haps/truth/state")
    leg = np.asarray(haps.t) <= m["vehicles"]["haps"]["mission"]["time_s"]
    assert np.abs(haps["pos_ned"][leg, 0]).max() < 10.0  # the HAPS held its course (its leg is north = 0)


SEED_MARGINS = {  # scenario: (pairs that must keep the margin, margin [m])
    "s9_converging": ([("uas1", "uas2")], CONVERGING_MARGIN),
    "s10_head_on": ([("uas1", "uas2")], HEAD_ON_MARGIN),
    "s11_roundabout": (None, HEAD_ON_MARGIN),
    "s12_overtake_2x": ([("uas1", "uas2")], OVERTAKE_MARGIN),
    "s13_overtake_3x": ([("uas1", "uas2")], OVERTAKE_MARGIN),
    "s13_overtake_4x": ([("uas1", "uas2")], OVERTAKE_MARGIN),
    "s14_pursuer": ([("uas1", "uas2")], HEAD_ON_MARGIN),
}


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(20))
@pytest.mark.parametrize("name", sorted(SEED_MARGINS))
def test_rules_scenarios_keep_their_margins_on_20_seeds(name, seed, tmp_path, record_property):
    """S9-S14 beyond their pinned seed: every listed pair (S11: every pair) keeps the case margin
    and the cooperative UAS complete (S14: uas1 is chased, only uas2 must complete). The minimum
    separation is recorded as the test's ``min_separation_m`` property (``--junitxml``)."""
    m, _ = fly(name, tmp_path, seed)
    pairs, margin = SEED_MARGINS[name]
    seps = m["separation"] if pairs is None else {f"{a}-{b}": m["separation"][f"{a}-{b}"] for a, b in pairs}
    record_property("min_separation_m", round(min(x["distance_m"] for x in seps.values()), 2))
    assert min(x["distance_m"] for x in seps.values()) >= margin, seps
    must = ["uas2"] if name == "s14_pursuer" else list(m["vehicles"])
    assert all(m["vehicles"][v]["mission"]["complete"] for v in must)


def test_a_give_way_uas_hovering_out_its_deadlock_keeps_its_case_until_the_peer_has_passed(tmp_path):
    """Draw 335 of the shipped cooperative-pairs envelope: a shallow converging pair at equal speeds
    where the give-way UAS (the intruder) finds no restricted path and hovers it out (R-18,
    ``rule:hold``). Its converging case stays open while it hovers, so no fresh head-on case
    re-opens the pair inside its margin when it flies on: one case, closed only once the pair is
    past its closest approach and keeps the 40 m converging margin. Ended by the hover itself,
    the case closed with ``own`` still approaching and the pair met head-on at 23.8 m."""
    from sim.batch import run_one
    from sim.encounters.campaign import load_campaign

    campaign = SCENARIOS.parent / "encounters" / "rules_cooperative_pairs_envelope.toml"
    c = load_campaign(campaign, tmp_path, draws=[335])
    (spec,) = [r for r in c.runs if r.run_id.endswith("_mitigated")]
    row = run_one(spec)
    log = RunLog(spec.log_path)
    e_own, e_int = events(log, "own"), events(log, "intruder")
    assert "rule:hold" in e_int
    opened = [e for e in e_own + e_int if e.startswith("rule:case_open:")]
    assert opened == [
        "rule:case_open:self-intruder:converging:right_of_way",
        "rule:case_open:self-own:converging:converging",
    ]
    assert row["metric.separation.own-intruder.min_horizontal_m"] >= CONVERGING_MARGIN
    assert row["metric.vehicles.own.mission.complete"] and row["metric.vehicles.intruder.mission.complete"]
