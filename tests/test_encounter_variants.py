"""Encounter campaigns with ``[[variant]]``: the same draws flown several ways against one shared
unmitigated run (sim/encounters/campaign.py, geometry.Variant), on the shipped
scenarios/encounters/rules_utm_vs_blind_vs_emergency.toml (docs/rules.md "UTM vs blind vs
emergency-only"): what each variant's scenario holds, that the draws and seeds are the same, the
per-variant outputs, and in the closed loop that the variants differ in what acts."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from sim.encounters.aggregate import Pair, summarise
from sim.encounters.campaign import load_campaign, run_campaign, tabulate
from sim.encounters.geometry import FOLLOW
from sim.encounters.model import CampaignError
from sim.replay.runlog import RunLog

CAMPAIGN = Path(__file__).resolve().parents[1] / "scenarios" / "encounters" / "rules_utm_vs_blind_vs_emergency.toml"
MODES = ("utm", "blind", "emergency", "unmitigated")


def _without(scen: dict, *keys: str) -> dict:
    """The scenario with the top-level ``keys`` and the vehicles' ``keys`` removed."""
    out = {k: v for k, v in scen.items() if k not in keys}
    out["vehicle"] = [{k: v for k, v in veh.items() if k not in keys} for veh in scen["vehicle"]]
    return out


def test_variants_fly_the_same_draws_with_their_own_planner_authority_and_links(tmp_path):
    c = load_campaign(CAMPAIGN, tmp_path, limit=3)
    assert c.modes == MODES and c.named and len(c.runs) == 4 * len(c.encounters) == 12
    for k, enc in enumerate(c.encounters):
        runs = dict(zip(MODES, c.runs[4 * k : 4 * k + 4], strict=True))
        assert [r.run_id for r in runs.values()] == [f"{c.name}_{enc.index:05d}_{m}" for m in MODES]
        assert all(
            r.params == {"encounter": enc.index, "mode": m, "seed": enc.seed, **enc.params} for m, r in runs.items()
        )
        scen = {m: r.scenario for m, r in runs.items()}
        assert len({s["seed"] for s in scen.values()}) == 1
        rules = c.setup.ownship["planner"]
        # utm: the authority over both vehicles' links, the campaign's rules planner on both
        assert scen["utm"]["utm"] == {"frame": 1.0, "lost_after": 3.0}
        assert [v["utm_link"] for v in scen["utm"]["vehicle"]] == [{"latency": 0.2, "loss": 0.02}] * 2
        assert [v["planner"] for v in scen["utm"]["vehicle"]] == [rules] * 2
        # blind: the same rules planners, no authority, no link of any kind
        assert [v["planner"] for v in scen["blind"]["vehicle"]] == [rules] * 2
        assert _without(scen["utm"], "utm", "utm_link", "name") == _without(scen["blind"], "name")
        # emergency only: the reach-set avoider without rules on both, nothing else changed
        assert [v["planner"]["options"] for v in scen["emergency"]["vehicle"]] == [
            {"period": 1.0, "intruder_margin": 4.55, "intruder_margin_vertical": 2.0}
        ] * 2
        assert "rules" in rules["options"]
        assert _without(scen["emergency"], "planner", "name") == _without(scen["blind"], "planner", "name")
        # unmitigated: both follow their missions, no authority, otherwise the same encounter
        assert [v["planner"] for v in scen["unmitigated"]["vehicle"]] == [FOLLOW] * 2
        assert _without(scen["unmitigated"], "planner", "name") == _without(scen["blind"], "planner", "name")


@pytest.mark.parametrize(
    ("variants", "message"),
    [
        ('[[variant]]\nname = "a"\n[[variant]]\nname = "a"', "variant: repeated name 'a'"),
        ('[[variant]]\nname = "unmitigated"', r"variant\[0\].name: letters, digits and _"),
        ('[[variant]]\nname = "a b"', r"variant\[0\].name"),
        ('[[variant]]\nname = "a"\nestimator = "perfect"', r"variant\[0\].estimator: unknown key"),
        ('[[variant]]\nname = "a"\nutm = 1', r"variant\[0\].utm: a table"),
        ("variant = 3", "variant: an array of tables"),
        ('[[variant]]\nname = "a"\nutm_link = { latency = -1 }', "latency"),
    ],
)
def test_bad_variants_are_one_line_errors(tmp_path, variants, message):
    text = CAMPAIGN.read_text()
    base = text[: text.index("[[variant]]")]
    path = tmp_path / "c.toml"
    # array-of-tables go last; a plain key must come before the first table
    path.write_text(base + variants + "\n" if variants.startswith("[[") else variants + "\n" + base)
    with pytest.raises(CampaignError, match=message) as err:
        load_campaign(path, tmp_path / "o", limit=1)
    assert "\n" not in str(err.value)


@pytest.mark.closed_loop
def test_ci_variants_differ_in_what_acts_and_share_the_unmitigated_run(tmp_path):
    """The shipped campaign's first draw (head-on-ish, 244°, 0.2 m sampled miss, 35.5 s run-in),
    every run kept: the UTM variant's vehicles get directives with their case from the authority
    and merge them (``rule:utm_*`` events); the blind one has no ``/utm`` topic but resolves by
    the rules of the air (manoeuvre roles); the emergency-only one has neither a ``/utm`` topic
    nor any rule event. One unmitigated run; outputs per variant."""
    path = tmp_path / "c.toml"
    path.write_text('keep_mcaps = "all"\n' + CAMPAIGN.read_text())
    out = tmp_path / "out"
    c = load_campaign(path, out, limit=1)
    summary = run_campaign(c, out, workers=2)
    logs = {m: RunLog(out / "runs" / f"{c.name}_00000_{m}.mcap") for m in MODES}

    def events(m: str) -> list[str]:
        return [
            e
            for v in ("own", "intruder")
            for msg in logs[m].topic(f"/{v}/plan/decision").messages
            for e in msg["events"]
        ]

    directed = [d for d in logs["utm"].topic("/utm/directive").messages if d["received_t"] is not None]
    assert {d["to"] for d in directed if d["cases"]} == {"own", "intruder"}
    assert any(e.startswith("rule:utm_") for e in events("utm"))
    for m in ("blind", "emergency", "unmitigated"):
        assert not [t for t in logs[m].topics if t.startswith("/utm")], m
    roles = ("rule:head_on", "rule:converging", "rule:overtake")
    assert any(e.startswith(roles) for e in events("blind")) and not any(
        e.startswith("rule:utm") for e in events("blind")
    )
    assert not any(e.startswith("rule:") for e in events("emergency"))
    assert set(summary) == {"utm", "blind", "emergency"}
    assert {s["nmac_unmitigated"] for s in summary.values()} == {summary["utm"]["nmac_unmitigated"]}
    assert json.loads((out / "summary.json").read_text()).keys() == summary.keys()
    with open(out / "encounters.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["mode"] for r in rows] == list(MODES) and len({r["seed"] for r in rows}) == 1
    report = (out / "report.md").read_text()
    assert all(f"| {m} |" in report for m in ("utm", "blind", "emergency"))


def _row(status: str, sep: float, nmac: bool, path: float, time: float | None) -> dict:
    """A batch row of a cooperative pair's run with the given outcome."""
    m = "metric.separation.own-intruder."
    return {
        "status": status,
        f"{m}min_horizontal_m": sep,
        f"{m}nmac": nmac,
        f"{m}lowc": sep < 40.0,
        "metric.vehicles.own.mission.complete": time is not None,
        "metric.vehicles.intruder.mission.complete": time is not None,
        "metric.vehicles.own.mission.time_s": time,
        "metric.vehicles.own.mission.path_length_m": path,
    }


def test_tabulate_pairs_each_variant_with_the_shared_unmitigated_run(tmp_path):
    """Per variant: its pairs with the unmitigated run of the same encounter; a failed variant run
    drops that encounter from its variant alone, a failed unmitigated run from every variant; the
    extra path and time are over the planned straight leg (5 m/s, time_to_cpa + after_cpa)."""
    c = load_campaign(CAMPAIGN, tmp_path, limit=2)
    plans = [e.params["time_to_cpa"] + c.setup.after_cpa for e in c.encounters]
    rows = [
        _row("completed", 60.0, False, 5 * plans[0] + 30.0, plans[0] + 6.0),  # utm
        _row("completed", 45.0, False, 5 * plans[0] + 10.0, plans[0] + 2.0),  # blind
        _row("failed", 0.0, False, 0.0, None),  # emergency
        _row("crashed", 0.5, True, 90.0, None),  # unmitigated: stops at the collision
        _row("completed", 80.0, False, 5 * plans[1] + 50.0, plans[1] + 10.0),
        _row("completed", 70.0, False, 5 * plans[1] + 20.0, plans[1] + 4.0),
        _row("completed", 4.0, True, 5 * plans[1] + 2.0, plans[1]),
        _row("failed", 0.0, False, 0.0, None),
    ]
    table, pairs = tabulate(c, rows)
    assert [r["mode"] for r in table] == list(MODES) * 2
    assert [r["extra_path_m"] for r in table[:2]] == pytest.approx([30.0, 10.0])
    assert [r["extra_time_s"] for r in table[:2]] == pytest.approx([6.0, 2.0])
    assert table[3]["extra_path_m"] == pytest.approx(90.0 - 5 * plans[0]) and table[3]["extra_time_s"] is None
    assert {m: len(p) for m, p in pairs.items()} == {"utm": 1, "blind": 1, "emergency": 0}
    s = summarise(pairs["utm"])
    assert s["nmac_unmitigated"] == 1 and s["nmac_mitigated"] == 0 and s["lowc_mitigated"] == 0
    assert s["extra_path_m_mean"] == pytest.approx(30.0) and s["min_separation_m_min"] == 60.0


def test_summary_spreads_of_extra_path_and_separation_by_hand():
    g = {"approach": "180 head-on"}
    pairs = [Pair(False, True, False, True, True, g, e, s) for e, s in ((10.0, 50.0), (40.0, 45.0), (None, 70.0))]
    pairs.append(Pair(False, False, False, False, True, g, 100.0, None))
    s = summarise(pairs)
    assert s["extra_path_m_mean"] == pytest.approx(50.0) and s["extra_path_m_median"] == pytest.approx(40.0)
    assert s["min_separation_m_min"] == 45.0 and s["min_separation_m_median"] == 50.0
    assert "extra_path_m_mean" not in summarise([Pair(False, True, False, True, True, g)])
