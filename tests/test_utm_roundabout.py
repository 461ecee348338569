"""A three-UAS roundabout formed by directives of the central UTM authority
(``scenarios/rules/roundabout_three_utm.toml``; spec §7.4 6.195-6.196; docs/rules.md "UTM
authority"): the authority merges the three cases into one roundabout, directs every member to
it, and the vehicles fly it. JSBSim quadrotors on their EKF estimates; every number read back
from the MCAP (``/utm/frame``, ``/utm/directive``, ``/<vehicle>/plan/rules``, truth, replay
metrics). Frames: GCF = ENU [m] from the scenario origin."""

from __future__ import annotations

import numpy as np
import pytest

from sim.replay.report import log_metrics
from sim.replay.runlog import RunLog

pytestmark = pytest.mark.closed_loop

UAS = ("uas1", "uas2", "uas3")
MARGIN = 50.0  # the roundabout margin: the largest case margin, head-on 10 units of 5 m [m]
CASES = {  # the cases the authority merges: ids -> encounter
    ("uas1", "uas2"): "head_on",
    ("uas1", "uas3"): "converging",
    ("uas2", "uas3"): "converging",
}


def directed_roundabouts(log: RunLog) -> dict[int, tuple[np.ndarray, float]]:
    """The authority's roundabout per UTM frame number: its centre (GCF [m]) and margin [m].
    There is one roundabout at a time, of the three; it forms with the head-on case's margin,
    and its margin is the largest of its open cases' in every frame (6.196: the head-on case
    may close before the two converging ones)."""
    out = {}
    for f in log.topic("/utm/frame").messages:
        if f["roundabouts"]:
            (r,) = f["roundabouts"]
            assert r["members"] == list(UAS), r
            assert r["margin_m"] == max(c["margin_m"] for c in f["active"] if c["encounter"] != "overtake"), r
            out[f["frame"]] = (np.array(r["centre_enu"]), r["margin_m"])
    assert out and out[min(out)][1] == MARGIN
    return out


def obeyed_manoeuvres(log: RunLog, vehicle: str, rbs: dict[int, tuple[np.ndarray, float]]) -> tuple[int, int]:
    """(frames in which the vehicle's roundabout manoeuvre (``head_on`` rule) acted on a UTM
    case at a directed centre (one of ``rbs``), frames in which it acted at all), over the
    vehicle's frames that follow a UTM frame with the roundabout (1 s frames: the decision at t
    holds the directive of frame t - 1; after the roundabout dissolves, a remaining head-on case
    is flown at its own point). A manoeuvre on a UTM case at another point fails."""
    centres = np.array([c for c, _ in rbs.values()])
    margins = [m for _, m in rbs.values()]
    directed = acted = 0
    for m in log.topic(f"/{vehicle}/plan/rules").messages:
        if round(m["t"]) - 1 not in rbs:
            continue
        utm = {tuple(d["case"]["ids"]): d["case"] for d in m["decisions"] if d["rule"] == "utm_case"}
        for d in m["decisions"]:
            if d["rule"] != "head_on":
                continue
            acted += 1
            case = utm.get(tuple(d["case"]["ids"]))
            if case is not None:
                gaps = np.linalg.norm(centres - d["case"]["collision_point_enu"], axis=1)
                k = int(np.argmin(gaps))
                assert gaps[k] < 1e-6, (vehicle, m["t"], gaps[k])
                # merged with the vehicle's own case: the larger margin (tab. 6.10)
                assert case["roles"] == ["roundabout", "roundabout"] and case["margin_m"] >= margins[k]
                directed += 1
    return directed, acted


def circulation(log: RunLog, vehicle: str, centre: np.ndarray) -> tuple[float, float]:
    """The vehicle's true closest distance to ``centre`` [m], and the share of its samples within
    two margins of it in which it moves counter-clockwise about it (the centre on its left: the
    right-hand roundabout)."""
    s = log.topic(f"/{vehicle}/truth/state")
    p, v = s["pos_ned"], s["vel_ned"]
    rel = np.c_[p[:, 1], p[:, 0]] - centre[:2]
    vel = np.c_[v[:, 1], v[:, 0]]
    dist = np.hypot(rel[:, 0], rel[:, 1])
    near = dist < 2 * MARGIN
    ccw = rel[near, 0] * vel[near, 1] - rel[near, 1] * vel[near, 0] > 0.0
    return float(dist.min()), float(ccw.mean())


def check_roundabout(log: RunLog) -> dict[str, float]:
    """The authority opens the three cases with their encounters, merges them into one
    roundabout with the largest margin and sends every member its cases re-targeted at the
    centre in every frame the roundabout stands. Every vehicle's roundabout manoeuvre acts on a
    directed centre in at least 90 % of its frames (the others: before the first directive of
    the case arrives); it keeps the margin from the first centre and circles it
    counter-clockwise. Every pair keeps the margin, all complete, nothing unresolved. Returns
    the closest pair separation and centre distance [m]."""
    opened: dict[tuple, str] = {}  # each pair's first case (a pair may meet again after the roundabout)
    for f in log.topic("/utm/frame").messages:
        for c in f["opened"]:
            opened.setdefault(tuple(c["ids"]), c["encounter"])
    assert opened == CASES
    rbs = directed_roundabouts(log)
    for d in log.topic("/utm/directive").messages:
        if d["frame"] in rbs:  # one or two cases: a member's chain may close first
            assert d["cases"], d
            assert all(np.allclose(c["collision_point_enu"], rbs[d["frame"]][0]) for c in d["cases"])
    centre = rbs[min(rbs)][0]  # the head cases' centre
    closest_centre = np.inf
    for v in UAS:
        directed, acted = obeyed_manoeuvres(log, v, rbs)
        assert acted and directed >= 0.9 * acted, (v, directed, acted)
        dist, ccw = circulation(log, v, centre)
        assert dist >= MARGIN and ccw >= 0.8, (v, dist, ccw)
        closest_centre = min(closest_centre, dist)
        ev = {e for m in log.topic(f"/{v}/plan/decision").messages for e in m["events"]}
        assert not any(e.startswith(("rule:case_unresolved", "rule:deadlock")) for e in ev), v
    m = log_metrics(log)
    assert all(x["mission"]["complete"] for x in m["vehicles"].values())
    pair = min(x["distance_m"] for x in m["separation"].values())
    assert pair >= MARGIN
    return {"pair_m": pair, "centre_m": closest_centre}


def test_three_uas_roundabout_formed_by_directives(fly):
    check_roundabout(fly("rules/roundabout_three_utm").log)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(20))
def test_three_uas_roundabout_on_20_seeds(seed, fly, scenario_data, record_property):
    """The CI check on seeds 0-19; JUnit properties ``pair_m`` (closest pair) and ``centre_m``
    (closest approach to the directed centre) [m]."""
    out = check_roundabout(fly({**scenario_data("rules/roundabout_three_utm"), "seed": seed}).log)
    for k, x in out.items():
        record_property(k, round(x, 2))
