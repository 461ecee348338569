"""The planner registry (sim/planner_registry.py): every registered type builds a planner that
carries its type's name (its log records are found by it), validates its options with a
field-named scenario error, and its options reach the planner it builds."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from sim.core.mission import Mission
from sim.planner_registry import PLANNERS, PlannerConfigError, make_planner
from sim.scenario import ScenarioError, parse_scenario

MISSION = Mission(np.array([[100.0, 0.0, -50.0], [200.0, 0.0, -50.0]]), 5.0, 2.0, start=np.array([0.0, 0.0, -50.0]))
REQUIRED = {"pursuit": {"target": "other"}}


def _scenario(aircraft: str, planner: dict) -> dict:
    alt = 18000.0 if aircraft == "haps" else 50.0
    return {
        "name": "registry",
        "seed": 1,
        "duration": 10.0,
        "origin": {"lat": 47.0, "lon": 8.0, "altitude": 0.0},
        "vehicle": [
            {
                "name": "v",
                "aircraft": aircraft,
                "initial": {"altitude": alt, "airspeed": 26.0 if aircraft == "haps" else 0.0},
                "mission": {
                    "cruise_speed": 26.0 if aircraft == "haps" else 5.0,
                    "waypoints": [{"north": 100, "east": 0, "altitude": alt}],
                },
                "planner": planner,
            }
        ],
    }


@pytest.mark.parametrize("name", list(PLANNERS))
def test_every_type_builds_a_planner_named_after_it_for_each_airframe_it_flies(name):
    entry = PLANNERS[name]
    for kind in entry.airframes:
        planner = make_planner(name, MISSION, kind, REQUIRED.get(name, {}))
        assert planner.name == name


@pytest.mark.parametrize("name", list(PLANNERS))
def test_an_unknown_option_is_a_field_named_scenario_error(name):
    aircraft = "quadrotor" if "multirotor" in PLANNERS[name].airframes else "haps"
    data = _scenario(aircraft, {"type": name, "options": {**REQUIRED.get(name, {}), "warp_factor": 9}})
    with pytest.raises(ScenarioError, match=r"vehicle\[0\]\.planner\.options\.warp_factor: unknown key"):
        parse_scenario(data)


@pytest.mark.parametrize(
    "planner, message",
    [
        ({"type": "reachset", "options": {"period": -1}}, "planner.options.period: out of range"),
        ({"type": "reachset", "options": {"separations": ["diagonal"]}}, "planner.options.separations[0]"),
        ({"type": "reachset", "options": {"rules_unit": 5.0}}, "rules_unit need rules"),
        ({"type": "geometric", "options": {"l": "four"}}, "planner.options.l: Input should be a valid integer"),
        ({"type": "geometric", "options": {"collision_radius": -1.0}}, "planner.options"),
        ({"type": "pursuit", "options": {}}, "planner.options.target: missing required field"),
        ({"type": "warp"}, "planner.type: unknown type 'warp'"),
        ({"type": "mptp"}, "mptp planner does not fly a multirotor"),
    ],
)
def test_bad_planner_settings_name_the_field(planner, message):
    with pytest.raises(ScenarioError, match=message.replace("[", r"\[").replace("]", r"\]").replace(".", r"\.")):
        parse_scenario(_scenario("quadrotor", planner))


def test_a_planner_table_without_type_follows_the_mission():
    scenario = parse_scenario(_scenario("quadrotor", {"rate_hz": 4.0}))
    assert scenario.vehicle[0].planner.type == "follow_mission"
    assert scenario.vehicle[0].planner.rate_hz == 4.0


def test_options_reach_the_planner_they_configure():
    rs = make_planner(
        "reachset", MISSION, "multirotor", {"period": 2.0, "intruder_margin": 3.0, "intruder_margin_vertical": 1.5}
    )
    base = make_planner("reachset", MISSION, "multirotor", {})
    assert rs.control.cfg.intruders.body_margin == 3.0 != base.control.cfg.intruders.body_margin
    assert rs.control.cfg.intruders.vertical_margin == 1.5 != base.control.cfg.intruders.vertical_margin
    # a multirotor turns in place (direct leg to a goal inside the turn circle), a fixed wing not
    assert base.turns_in_place and not make_planner("reachset", MISSION, "fixed_wing", {}).turns_in_place
    assert rs.control.sma.automata[0].table.config.period == 2.0 != base.control.sma.automata[0].table.config.period
    rules = make_planner("reachset", MISSION, "multirotor", {"rules": ["head_on"], "rules_unit": 5.0})
    assert type(rules).__name__ == "RulesAvoider" and rules.rules.unit == 5.0 and rules.rules.enabled == ("head_on",)
    geo = make_planner("geometric", MISSION, "multirotor", {"select_margin_m": 0.3})
    assert geo.config.select_margin_m == 0.3
    mptp = make_planner("mptp", MISSION, "fixed_wing", {"horizon_s": 1800.0})
    assert mptp.cfg.horizon_s == 1800.0 and mptp.cfg.tas_mps == MISSION.cruise_speed  # cruise from the mission
    pinned = make_planner("mptp", MISSION, "fixed_wing", {"tas_mps": 30.0})
    assert pinned.cfg.tas_mps == 30.0  # a given option wins over the mission's value
    assert make_planner("pursuit", MISSION, "multirotor", {"target": "uas2"}).target == "uas2"


def test_registry_refuses_unknown_types_and_wrong_airframes():
    with pytest.raises(PlannerConfigError, match="unknown planner"):
        make_planner("warp", MISSION)
    with pytest.raises(PlannerConfigError, match="does not fly a multirotor"):
        make_planner("mptp", copy.deepcopy(MISSION), "multirotor")


def test_the_mptp_rolls_at_the_haps_controllers_bank_slew_rate():
    """A HAPS's MPTP simulates its turns at the bank-command slew rate of the HAPS's own gains
    (the rate the autopilot rolls at), the shipped 6 deg/s or a tuned one; the option wins."""
    import dataclasses
    import math
    from pathlib import Path

    from aircraft.haps.gains import HapsGains
    from aircraft.registry import get_airframe
    from sim.scenario import load_scenario
    from sim.vehicle_setup import mission_from_config, scenario_planner

    scenario, _ = load_scenario(Path(__file__).resolve().parents[1] / "scenarios" / "mptp" / "storm_crossing.toml")
    cfg = scenario.vehicle[0]
    mission = mission_from_config(cfg, scenario.origin_point)
    af = get_airframe(cfg.aircraft)

    def roll_rate(gains: HapsGains, spec=cfg) -> float:
        return scenario_planner(spec, mission, af, gains, scenario.wind, scenario.origin.altitude).cfg.roll_rate_max

    shipped = HapsGains.load()
    assert roll_rate(shipped) == shipped.roll_rate_limit_rad_s == math.radians(6.0)
    slow = dataclasses.replace(shipped, roll_rate_limit_rad_s=math.radians(2.5))
    assert roll_rate(slow) == math.radians(2.5)
    options = {**cfg.planner.options.model_dump(exclude_unset=True), "roll_rate_max": math.radians(4.0)}
    own = cfg.model_copy(update={"planner": cfg.planner.model_copy(update={"options": options})})
    assert roll_rate(slow, own) == math.radians(4.0)
