"""Encounter construction: from sampled parameters to a scenario whose unmitigated closest approach is
the sampled one.

Local NED [m] from the scenario origin, altitudes MSL [m], speeds [m/s], sim time [s]. Both
vehicles fly straight, constant-velocity legs through their closest point of approach (CPA) at
``time_to_cpa``: the ownship passes over (north, east) = (0, 0) at ``altitude``; the intruder is
then ``hmd`` to the right of the horizontal relative velocity (intruder minus ownship) and ``vmd``
above. With the relative position at that time perpendicular to the relative velocity, that time is
the horizontal CPA and ``hmd`` its miss distance. Each vehicle starts ``time_to_cpa`` back along
its leg at its cruise speed (a multirotor already moving: its initial airspeed). The ownship's one
waypoint (its goal) lies ``after_cpa`` beyond the CPA, and so does a cooperative intruder's; a
non-cooperative intruder's lies :data:`RUN_ON_S` past the run's end, so it flies its leg at constant
speed to the end (it never brakes to hover on or beside the ownship's route); the run ends when the
ownship's mission (and a cooperative intruder's) is complete. A cooperative triple
(``intruder.count = 2``) adds a second cooperative intruder built the same way from
``approach_angle_2``, ``intruder_speed_2`` and ``hmd_2`` (level, at the ownship's altitude),
meeting the ownship at the same time: all three pass their closest approaches together. A
:class:`Variant` names one way of flying the mitigated run (its planner, UTM authority and links),
so one encounter can be flown under several.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sim.encounters.model import CampaignError

INTRUDER_KINDS = ("object", "quadrotor", "haps", "cooperative")
MODES = ("mitigated", "unmitigated")
OWN, INTRUDER, INTRUDER2 = "own", "intruder", "intruder2"
FOLLOW = {"type": "follow_mission"}
DEFAULT_ORIGIN = {"lat": 47.0, "lon": 8.0, "altitude": 400.0}  # [deg, deg, m MSL]
# [s] a non-cooperative intruder's waypoint lies this far along its leg past the run's end: more
# than a multirotor's carrot lead (5 m) at any speed above 0.5 m/s, so it never slows down
RUN_ON_S = 10.0


@dataclass(frozen=True, slots=True)
class EncounterSetup:
    """What every encounter of a campaign shares. ``ownship``: ``aircraft``, ``planner`` (a
    scenario planner table), optional ``acceptance_radius`` [m], ``estimator`` and ``initial``
    (scenario initial-state fields over the generated ones, e.g. ``trim = false``); ``intruder``:
    ``kind`` (:data:`INTRUDER_KINDS`; ``cooperative``: a quadrotor running the ownship's planner
    when mitigated), ``count`` (2: a cooperative triple), ``radius`` [m] of an object, optional
    ``acceptance_radius``, ``estimator``, ``initial``. ``metrics``: the
    scenario's ``[metrics]`` table (NMAC cylinder, well clear)."""

    ownship: dict
    intruder: dict
    altitude: float = 420.0
    after_cpa: float = 10.0
    slack: float = 30.0
    origin: dict = field(default_factory=lambda: dict(DEFAULT_ORIGIN))
    surveillance_rate_hz: float = 2.0
    metrics: dict = field(default_factory=dict)


@dataclass(frozen=True, slots=True)
class Variant:
    """One way of flying an encounter's mitigated run, named ``name`` (its mode in the outputs).
    ``planner``: the scenario planner table of the ownship (and of cooperative intruders) instead
    of the campaign's; ``utm``: the scenario's ``[utm]`` table (a central authority); ``utm_link``
    and ``peer_link``: the ``[vehicle.utm_link]`` / ``[vehicle.peer_link]`` tables of every vehicle
    running that planner. None: the campaign's planner, no authority, no link."""

    name: str = "mitigated"
    planner: dict | None = None
    utm: dict | None = None
    utm_link: dict | None = None
    peer_link: dict | None = None


@dataclass(frozen=True, slots=True)
class Leg:
    """A straight leg: start NED [m] (down = -(altitude - origin altitude)), velocity NED [m/s]."""

    start: np.ndarray
    velocity: np.ndarray

    def at(self, t: float) -> np.ndarray:
        return self.start + self.velocity * t


def velocities(p: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """Ownship and intruder velocities NED [m/s] of parameters ``p``."""
    psi_o = math.radians(p["own_heading"])
    psi_i = psi_o + math.radians(p["approach_angle"])
    v_o = np.array([p["own_speed"] * math.cos(psi_o), p["own_speed"] * math.sin(psi_o), -p["own_vertical_rate"]])
    v_i = np.array(
        [p["intruder_speed"] * math.cos(psi_i), p["intruder_speed"] * math.sin(psi_i), -p["intruder_vertical_rate"]]
    )
    return v_o, v_i


def relative_speed(p: dict[str, float]) -> float:
    """Horizontal speed of the intruder relative to the ownship [m/s]."""
    v_o, v_i = velocities(p)
    return float(np.hypot(*(v_i[:2] - v_o[:2])))


def second_intruder(p: dict[str, float]) -> dict[str, float]:
    """The parameters of a triple's second intruder as an encounter with the ownship: its own
    course, speed and horizontal miss; level at the ownship's altitude."""
    return p | {
        "approach_angle": p["approach_angle_2"],
        "intruder_speed": p["intruder_speed_2"],
        "hmd": p["hmd_2"],
        "vmd": 0.0,
        "intruder_vertical_rate": 0.0,
    }


def intruder_count(setup: EncounterSetup) -> int:
    """1, or 2 for a cooperative triple."""
    return int(setup.intruder.get("count", 1))


def legs(p: dict[str, float], setup: EncounterSetup) -> tuple[Leg, Leg]:
    """Ownship and intruder legs of parameters ``p`` (see :mod:`sim.encounters.model`)."""
    v_o, v_i = velocities(p)
    rel = v_i[:2] - v_o[:2]
    n = float(np.hypot(*rel))
    if n < 1e-6:
        raise CampaignError(f"encounter {p}: equal horizontal velocities: no closest approach")
    right = np.array([-rel[1], rel[0]]) / n
    down_cpa = -(setup.altitude - setup.origin["altitude"])
    cpa_o = np.array([0.0, 0.0, down_cpa])
    cpa_i = np.array([*(p["hmd"] * right), down_cpa - p["vmd"]])
    t = p["time_to_cpa"]
    return Leg(cpa_o - v_o * t, v_o), Leg(cpa_i - v_i * t, v_i)


def start_within(p: dict[str, float], setup: EncounterSetup, horizontal: float, vertical: float) -> bool:
    """Whether two of the encounter's vehicles start less than ``horizontal`` [m] apart
    horizontally and ``vertical`` [m] vertically (a triple: any pair)."""
    own, intruder = legs(p, setup)
    starts = [own.start, intruder.start]
    if intruder_count(setup) == 2:
        starts.append(legs(second_intruder(p), setup)[1].start)
    return any(
        math.hypot(*(a[:2] - b[:2])) < horizontal and abs(a[2] - b[2]) < vertical
        for k, a in enumerate(starts)
        for b in starts[k + 1 :]
    )


def _vehicle(
    name: str, aircraft: str, leg: Leg, setup: EncounterSetup, end_t: float, cfg: dict, planner: dict, links: dict
) -> dict:
    """A scenario ``[[vehicle]]`` flying ``leg`` from t = 0 to its waypoint at ``end_t`` [s], with
    the ``links`` tables (``utm_link``, ``peer_link``)."""
    alt0 = setup.origin["altitude"]
    end = leg.at(end_t)
    horizontal = float(np.hypot(*leg.velocity[:2]))
    vehicle = {
        "name": name,
        "aircraft": aircraft,
        "initial": {
            "north": float(leg.start[0]),
            "east": float(leg.start[1]),
            "altitude": alt0 - float(leg.start[2]),
            "airspeed": horizontal,
            "heading": math.degrees(math.atan2(leg.velocity[1], leg.velocity[0])),
            **cfg.get("initial", {}),
        },
        "mission": {
            "cruise_speed": float(np.linalg.norm(leg.velocity)) if aircraft != "haps" else horizontal,
            "acceptance_radius": float(cfg.get("acceptance_radius", 2.0)),
            "waypoints": [{"north": float(end[0]), "east": float(end[1]), "altitude": alt0 - float(end[2])}],
        },
        "planner": planner,
    }
    if "estimator" in cfg:
        vehicle["estimator"] = cfg["estimator"]
    return vehicle | links


def build_scenario(
    p: dict[str, float], setup: EncounterSetup, seed: int, mode: str, name: str, variant: Variant | None = None
) -> dict:
    """The scenario mapping of one encounter flown in ``mode`` (:data:`MODES`): mitigated, the
    ownship (and a cooperative intruder) run the campaign's planner, or the ``variant``'s, with its
    authority and links; unmitigated, every vehicle runs ``follow_mission`` (no authority)."""
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    own_leg, int_leg = legs(p, setup)
    end_t = p["time_to_cpa"] + setup.after_cpa
    duration = end_t + setup.slack
    kind = setup.intruder["kind"]
    mitigated = mode == "mitigated"
    variant = variant or Variant()
    planner = (variant.planner or setup.ownship["planner"]) if mitigated else FOLLOW
    links = {k: getattr(variant, k) for k in ("utm_link", "peer_link") if mitigated and getattr(variant, k)}
    int_end_t = end_t if kind == "cooperative" else duration + RUN_ON_S
    wind = math.radians(p["wind_direction"])
    scen: dict = {
        "name": name,
        "seed": seed,
        "duration": duration,
        "origin": dict(setup.origin),
        "surveillance": {
            "rate_hz": setup.surveillance_rate_hz,
            "latency": p["surveillance_latency"],
            "dropout": p["surveillance_dropout"],
            "position_noise_horizontal": p["surveillance_noise_h"],
            "position_noise_vertical": p["surveillance_noise_v"],
        },
        "wind": {"north": p["wind_speed"] * math.cos(wind), "east": p["wind_speed"] * math.sin(wind)},
        "metrics": dict(setup.metrics),
        "vehicle": [_vehicle(OWN, setup.ownship["aircraft"], own_leg, setup, end_t, setup.ownship, planner, links)],
    }
    if mitigated and variant.utm is not None:
        scen["utm"] = dict(variant.utm)
    alt0 = setup.origin["altitude"]
    if kind == "object":
        scen["object"] = [
            {
                "id": INTRUDER,
                "radius": float(setup.intruder.get("radius", 0.5)),
                "north": float(int_leg.start[0]),
                "east": float(int_leg.start[1]),
                "altitude": alt0 - float(int_leg.start[2]),
                "velocity": dict(zip(("north", "east", "down"), map(float, int_leg.velocity), strict=True)),
            }
        ]
    else:
        aircraft = "haps" if kind == "haps" else "quadrotor"
        coop = kind == "cooperative"
        int_planner = planner if coop else FOLLOW
        int_links = links if coop else {}
        int_legs = [(INTRUDER, int_leg)]
        if intruder_count(setup) == 2:
            int_legs.append((INTRUDER2, legs(second_intruder(p), setup)[1]))
        scen["vehicle"] += [
            _vehicle(n, aircraft, leg, setup, int_end_t, setup.intruder, int_planner, int_links) for n, leg in int_legs
        ]
    scen["stop_when_complete"] = [v["name"] for v in scen["vehicle"] if v["name"] == OWN or kind == "cooperative"]
    return scen
