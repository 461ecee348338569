"""Weather cases sent by the central UTM authority (spec §7.5, §7.1; ``utm.weather``;
docs/rules.md "UTM authority"): the weather service's nowcasts go to the authority, which sends
every vehicle the weather cases of the cells its filed route crosses in its directives. A storm
cell crossing two routes (``scenarios/rules/weather_two_routes_utm.toml``): both UAS handle it.
JSBSim quadrotors on their EKF estimates; every number read back from the MCAP. Frames: GCF = ENU
[m] from the scenario origin."""

from __future__ import annotations

import copy

import jsonschema
import numpy as np
import pytest
import shapely
from shapely.geometry import Polygon

from avoidance.utm.weather_case import WeatherCase, crossing
from sim import log_schemas as S
from sim.replay.rerun import rerun_planner
from sim.replay.runlog import RunLog
from sim.scenario import parse_scenario
from tests.test_rules_parts import WEATHER_BAND_M, check_weather_case

QUADS = ("quad1", "quad2")
CELL_ENU = np.array([[-14.8, 197.8], [-50.0, 150.7], [-16.1, 102.7], [40.0, 120.0], [40.9, 178.8]])  # the scenario's


def directed_weather(log: RunLog, vehicle: str) -> list[tuple[int, list[dict]]]:
    """(frame, weather case records) of every directive to ``vehicle``."""
    return [(d["frame"], d["weather"]) for d in log.topic("/utm/directive").messages if d["to"] == vehicle]


def test_crossing_picks_the_cells_a_route_crosses_within_the_band_and_sweeps_moving_ones():
    """Hand-made: a 20 m square at (100, 0) with a 20 m band; routes along y = 25 (15 m off the
    body: inside the band), y = 35 (25 m off: outside) and y = 35 for a cell drifting +y at
    1 m/s (its band reaches the route after 5 s), a route ending 30 m before it, and a point."""
    body = Polygon([(90, -10), (110, -10), (110, 10), (90, 10)])
    static = WeatherCase("c", 0.0, body, 20.0)
    moving = WeatherCase("m", 0.0, body, 20.0, np.array([0.0, 1.0]))
    line = lambda y, x1=200.0: np.array([[0.0, y, 0.0], [x1, y, 0.0]])  # noqa: E731
    assert crossing([static], line(25.0), 0.0) == [static]
    assert crossing([static], line(35.0), 0.0) == []
    assert crossing([moving], line(35.0), 10.0) == [moving]
    assert crossing([moving], line(35.0), 4.0) == []
    assert crossing([static], line(0.0, 60.0), 0.0) == []
    assert crossing([static], np.array([[100.0, 19.0, 0.0]]), 0.0) == [static]


def test_weather_case_record_round_trips():
    w = WeatherCase("cell0", 3.0, Polygon(CELL_ENU), 25.0, np.array([1.0, -2.0]))
    back = WeatherCase.from_record(w.record())
    assert back.record() == w.record() and shapely.equals(back.body, w.body)


def test_utm_weather_needs_the_weather_service(scenario_data):
    data = copy.deepcopy(scenario_data("rules/weather_two_routes_utm"))
    del data["weather"]
    with pytest.raises(ValueError, match=r"utm\.weather needs the \[weather\] section"):
        parse_scenario(data, "x")


def check_directed_weather(flight) -> dict[str, float]:
    """The vehicles get no nowcast of their own; the authority sends both, in at least 20
    frames, the scripted cell as weather case ``cell0`` (its body, the 25 m band of their
    registration); both obey it (``rule:utm_weather:cell0``) and pass it like a roundabout:
    never inside, the band kept within 2.5 m, quad1 east of it, quad2 south of it, both complete
    (:func:`tests.test_rules_parts.check_weather_case`). Returns each one's closest distance to
    the body [m]."""
    log = flight.log
    for d in log.topic("/utm/directive").messages:
        jsonschema.validate(d, S.UTM_DIRECTIVE)
    closest = {}
    for v in QUADS:
        assert all(not th["storms"] for th in log.topic(f"/{v}/threats").messages), v  # no own nowcast
        sent = directed_weather(log, v)
        assert len([f for f, w in sent if w]) >= 20, v
        for _, ws in sent:
            for w in ws:
                assert w["id"] == "cell0" and w["margin_m"] == WEATHER_BAND_M and not w["moving"]
                assert shapely.equals_exact(Polygon(w["body_enu"]), Polygon(CELL_ENU), tolerance=1e-6)
        events = {e for m in log.topic(f"/{v}/plan/decision").messages for e in m["events"]}
        assert "rule:utm_weather:cell0" in events
        closest[v] = check_weather_case(flight, v, "static")
    return closest


@pytest.mark.closed_loop
def test_storm_cell_crossing_two_routes_is_a_weather_case_sent_by_the_authority(fly):
    """:func:`check_directed_weather` on the file's seed, and the re-run planner reproduces
    every plan of quad1 from the logged directives (weather cases included; quad2's re-run is
    the same code for twice the CI time)."""
    flight = fly("rules/weather_two_routes_utm")
    check_directed_weather(flight)
    rep = rerun_planner(flight.path, "quad1")
    assert rep.differences == [] and rep.plans > 0


@pytest.mark.slow
@pytest.mark.closed_loop
@pytest.mark.parametrize("seed", range(20))
def test_directed_weather_case_on_20_seeds(seed, fly, scenario_data, record_property):
    """:func:`check_directed_weather` on seeds 0-19; JUnit properties ``<vehicle>_m``: the
    closest distance to the body [m]."""
    out = check_directed_weather(fly({**scenario_data("rules/weather_two_routes_utm"), "seed": seed}))
    for v, x in out.items():
        record_property(f"{v}_m", round(x, 2))
