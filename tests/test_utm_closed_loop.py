"""The central UTM authority in the closed loop (sim/utm_authority.py; docs/rules.md "UTM
authority"): S9 flown with the authority (roles and margin of the virtual-UTM S9), a C2/UTM
link outage in the middle of the encounter, and a forged UTM case. JSBSim quadrotors on their EKF estimates; every
number read back from the MCAP (replay metrics, decision events, ``/utm/*`` topics)."""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path

import jsonschema
import numpy as np
import pytest

from sim import log_schemas as S
from sim.replay import rerun
from sim.replay.report import log_metrics, write_report
from sim.replay.rerun import rerun_planner
from sim.replay.runlog import RunLog

pytestmark = pytest.mark.closed_loop

CONVERGING_MARGIN = 8 * 5.0  # (6.193) with the scenarios' rules unit of 5 m [m]
GIVE_WAY = "rule:converging:self-uas2:converging:converging"  # uas1 resolves as the give-way UAS
OUTAGE = (15.0, 40.0)  # uas1's link outage [s]: the case is open at the UTM from ~3 s, closest approach ~35 s
GHOST = {"north": 20.0, "east": 100.0, "altitude": 420.0}  # a forged collision point on uas2's course


def events(log: RunLog, vehicle: str) -> list[tuple[float, str]]:
    dec = log.topic(f"/{vehicle}/plan/decision")
    return [(float(t), e) for t, m in zip(dec.t, dec.messages, strict=True) for e in m["events"]]


def names(evs: list[tuple[float, str]]) -> set[str]:
    return {e for _, e in evs}


def separation(log: RunLog) -> float:
    return log_metrics(log)["separation"]["uas1-uas2"]["distance_m"]


def complete(log: RunLog) -> bool:
    return all(v["mission"]["complete"] for v in log_metrics(log)["vehicles"].values())


def degraded(data: dict, seed: int | None = None) -> dict:
    """S9 with the authority, uas1's link out during :data:`OUTAGE` and a forged head-on case
    about a vehicle ``ghost`` (which does not exist) sent to uas2 from 5 s on."""
    d = copy.deepcopy(data)
    d["vehicle"][0]["utm_link"]["outage"] = [{"start": OUTAGE[0], "end": OUTAGE[1]}]
    d["utm"]["spoof"] = [{"vehicle": "uas2", "peer": "ghost", "at": 5.0, **GHOST, "margin": 50.0}]
    if seed is not None:
        d["seed"] = seed
    return d


def with_seed(data: dict, seed: int) -> dict:
    return {**copy.deepcopy(data), "seed": seed}


def check_roles_and_margin(log: RunLog, directed: bool = True) -> None:
    """The S9 outcome: uas1 gives way, both complete, the converging margin kept, no unresolved
    case; ``directed``: uas2 is directed with the right of way and holds its course (no
    manoeuvre rule acts for it; with the authority out of touch with uas1 it resolves on its own
    case, whose role its estimates may leave in doubt: the virtual UTM's give-way rule)."""
    e1, e2 = names(events(log, "uas1")), names(events(log, "uas2"))
    assert complete(log)
    assert separation(log) >= CONVERGING_MARGIN
    assert GIVE_WAY in e1
    if directed:
        assert "rule:utm_case:self-uas2:converging:converging" in e1
        assert "rule:utm_case:self-uas1:converging:right_of_way" in e2
        holds = not any(e.startswith(("rule:converging", "rule:right_plane_heading", "rule:head_on")) for e in e2)
        assert holds, sorted(e2)
    bad = sorted(e for e in e1 | e2 if e.startswith(("rule:case_unresolved", "rule:deadlock")))
    assert not bad, bad


@pytest.fixture(scope="module")
def s9_utm(tmp_path_factory, fly_in):
    return fly_in(tmp_path_factory.mktemp("utm"), "rules/s9_converging_utm").log


@pytest.fixture(scope="module")
def s9_degraded(tmp_path_factory, fly_in, scenario_data):
    return fly_in(tmp_path_factory.mktemp("utm"), degraded(scenario_data("rules/s9_converging_utm")), "degraded").log


def test_s9_with_the_authority_gives_the_same_roles_and_keeps_the_margin(s9_utm):
    log = s9_utm
    check_roles_and_margin(log)
    frames = log.topic("/utm/frame").messages
    opened = [c for f in frames for c in f["opened"]]
    assert [(c["ids"], c["roles"], c["trajectory"]) for c in opened] == [
        (["uas1", "uas2"], ["converging", "right_of_way"], True)  # from the filed plans (intent)
    ]
    first_own = min(t for t, e in events(log, "uas1") if e.startswith("rule:case_open"))
    assert opened[0]["t"] <= first_own  # on intent, no later than the vehicles' own books
    assert not log.has("/utm/breach")
    # every delivered directive is acknowledged unless the ack is lost (2 % loss on the uplink)
    sent = [d for d in log.topic("/utm/directive").messages if d["received_t"] is not None]
    acks = log.topic("/utm/ack").messages
    assert {(a["from"], a["frame"]) for a in acks} <= {(d["to"], d["frame"]) for d in sent}
    assert 0.9 * len(sent) <= len(acks) < len(sent) + 1
    assert len(sent) < len(log.topic("/utm/directive").messages)  # the 2 % loss acts
    notes = log.topic("/utm/notification").messages
    assert all(abs(n["t"] - n["sent_t"] - 0.2) < 0.11 for n in notes)  # 0.2 s latency, 0.1 s log tick


def test_rerun_of_the_authority_run_needs_the_directives(s9_utm, monkeypatch):
    """The vehicle's planner re-run on the log reproduces every plan with the logged directives
    (tests/test_replay_rerun.py) and not without them: the directives act on the plans."""
    path = s9_utm.path
    assert rerun_planner(path, "uas1").differences == []
    monkeypatch.setattr(rerun._Directives, "deliver", lambda self, flying, t: None)  # never handed over
    rep = rerun_planner(path, "uas1")
    assert rep.same < rep.plans


def test_link_outage_mid_encounter_falls_back_to_blind_mode_and_keeps_the_margin(s9_degraded):
    log = s9_degraded
    check_roles_and_margin(log)
    e1 = events(log, "uas1")
    blind = [t for t, e in e1 if e == "rule:utm_blind"]
    back = [t for t, e in e1 if e == "rule:utm_cooperative"]
    assert len(blind) == 1 and OUTAGE[0] + 3.0 <= blind[0] <= OUTAGE[0] + 5.0  # lost_after 3 s, 1 s frames
    assert len(back) == 2 and back[0] < OUTAGE[0] and OUTAGE[1] <= back[1] <= OUTAGE[1] + 2.0
    during = [e for t, e in e1 if blind[0] <= t < back[1]]
    assert GIVE_WAY in during  # blind: the rules of the air on its own case
    assert not any(e.startswith("rule:utm_case") for e in during)
    for msg in log.topic("/utm/link").messages:
        jsonschema.validate(msg, S.UTM_LINK)
    link = [(m["vehicle"], m["state"]) for m in log.topic("/utm/link").messages]
    assert ("uas1", "lost") in link and link.index(("uas1", "lost")) < len(link) - 1
    lost_t = next(m["t"] for m in log.topic("/utm/link").messages if m["state"] == "lost")
    assert OUTAGE[0] + 3.0 <= lost_t <= OUTAGE[0] + 5.0
    assert any("utm: link to uas1 lost" in text for _, text in log.events())


def test_forged_case_about_a_vehicle_that_does_not_exist_is_not_obeyed(s9_degraded):
    log = s9_degraded
    for msg in log.topic("/utm/spoof").messages:  # the shipped scenario has none (tests/test_log_contracts.py)
        jsonschema.validate(msg, S.UTM_SPOOF)
    e2 = events(log, "uas2")
    ignored = [t for t, e in e2 if e == "rule:utm_unconfirmed:self-ghost:head_on:roundabout"]
    assert ignored and min(ignored) < 12.0
    assert not any("ghost" in e for _, e in e2 if not e.startswith("rule:utm_unconfirmed"))
    # uas2 flies through the forged collision point instead of circling it at 50 m
    p = log.topic("/uas2/truth/state")["pos_ned"]
    ghost = np.array([GHOST["north"], GHOST["east"], -(GHOST["altitude"] - 400.0)])
    assert np.linalg.norm(p - ghost, axis=1).min() < 5.0


def trail(log: RunLog, out: Path) -> list[tuple[float, float | None, str, str]]:
    """The rows of the Markdown replay report's decision trail: from, until (None: an instant)
    [s], who, decision."""
    report, _ = write_report(log.path, out)
    section = report.read_text().split("## Decision trail\n\n", 1)[1].split("\n\n", 1)[0]
    rows = []
    for line in section.splitlines()[2:]:
        start, end, who, what = (x.strip() for x in line.strip("|").split("|"))
        rows.append((float(start), float(end) if end else None, who, what))
    return rows


def test_replay_report_tables_the_decision_trail(s9_degraded, tmp_path):
    """``cosim replay``'s report: the authority's case with its roles, uas1 obeying it, the
    authority losing uas1's link and uas1 going blind in the outage (obeying nothing), directed
    again after it, the forged case sent to uas2 and uas2 ignoring it, in time order."""
    rows = trail(s9_degraded, tmp_path)
    assert rows == sorted(rows, key=lambda r: (r[0], r[2], r[3]))

    def find(who: str, what: str) -> list[tuple[float, float | None, str, str]]:
        return [r for r in rows if r[2] == who and r[3] == what]

    (case,) = find("utm", "case uas1-uas2 converging: uas1 converging, uas2 right_of_way, margin 40 m")
    obey = find("uas1", "rule:utm_case:self-uas2:converging:converging")
    assert obey and obey[0][0] >= case[0]
    (lost,) = find("utm", "link to uas1 lost")
    (blind,) = find("uas1", "rule:utm_blind")
    assert lost[1] is None and all(OUTAGE[0] + 3.0 <= r[0] <= OUTAGE[0] + 5.0 for r in (lost, blind))
    assert any(r[1] is not None and r[1] < blind[0] for r in obey)
    assert not any(blind[0] <= r[0] < OUTAGE[1] for r in obey)
    assert any(OUTAGE[1] <= r[0] <= OUTAGE[1] + 2.0 for r in find("uas1", "rule:utm_cooperative"))
    (forged,) = find("utm", "forged case ghost to uas2")
    assert forged[0] == 5.0
    assert find("uas2", "rule:utm_unconfirmed:self-ghost:head_on:roundabout")


SEEDS = range(20)


@pytest.mark.slow
@pytest.mark.parametrize("seed", SEEDS)
def test_s9_authority_on_20_seeds(seed, tmp_path, fly_in, scenario_data, record_property):
    """Per seed: S9 with the authority, and with the authority, uas1's link outage and the forged
    case: both give the roles of the virtual-UTM S9 (uas1 gives way, uas2 holds its course) and
    keep the margin (the virtual-UTM S9 on the same seeds:
    tests/test_rules_closed_loop.py::test_rules_scenarios_keep_their_margins_on_20_seeds). The
    separations are recorded as properties (``--junitxml``)."""
    utm = scenario_data("rules/s9_converging_utm")
    runs = {
        "utm": fly_in(tmp_path, with_seed(utm, seed), "utm").log,
        "outage": fly_in(tmp_path, degraded(utm, seed), "outage").log,
    }
    for name, log in runs.items():
        record_property(f"{name}_separation_m", round(separation(log), 2))
    check_roles_and_margin(runs["utm"])
    check_roles_and_margin(runs["outage"], directed=False)
    assert "rule:utm_blind" in names(events(runs["outage"], "uas1"))
    assert not any("ghost" in e for e in names(events(runs["outage"], "uas2")) if "unconfirmed" not in e)


def test_shipped_scenarios_differ_only_by_the_authority():
    """The authority run is the virtual-UTM S9 plus the [utm] section and the links only."""
    root = Path(__file__).resolve().parents[1] / "scenarios" / "rules"
    a = tomllib.loads((root / "s9_converging.toml").read_text())
    b = tomllib.loads((root / "s9_converging_utm.toml").read_text())
    for v in b["vehicle"]:
        assert v.pop("utm_link") == {"latency": "0.2 s", "loss": 0.02}
    assert b.pop("utm") == {"frame": "1 s", "lost_after": "3 s"}
    assert {**b, "name": a["name"]} == a
