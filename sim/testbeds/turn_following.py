"""Controlled experiment: the JSBSim HAPS flies one MPTP fly-over plan with written-out turns.

Why are the turn models' plans flown wide (issue 23)? Here everything but the factor under test
is fixed: truth as the estimate (ideal sensors), a steady wind or none, the HAPS's autopilot
and the fixed-wing plan follower at 10 Hz on JSBSim at 120 Hz, at 18 km and 26 m/s. The plan
is built by the MPTP's own turn model (turnmodel.written_out) from four states: a 3 km straight,
a 40 deg right turn, a 40 deg left turn, a straight. The measure is the one of the closed-loop
runs (mptp_turn_vertices.corner_cross_track): the closest approach of the true track to each
written-out vertex, + inside the turn (a cut corner), - outside. Frames: local-level NED [m].

Factors: the turn model (``approximate``, ``simulated``), the follower's turn-rate feed-forward
(the plan's ``turn_rates`` given to it or withheld), the L1 period [s], a steady wind (north,
east) [m/s], and a replan in the first turn (``replan_turn_rad``: a new plan made from the true
state ``REPLAN_INTO_TURN_S`` into the first turn, as the MPTP makes it: its lead-in, then a
fly-over turn starting at the aircraft's bank or, ``banked_start`` False, wings level; only the
new plan's vertices are measured). L1 on the chords of an arc of radius R without feed-forward rides outside it by d
with 4 damping^2 d / L1^2 = 1 / (R + d) (guidance/l1.py); ``predicted_offset_m`` gives d.

``python -m sim.testbeds.turn_following`` prints the Markdown table of CASES and the HAPS's lag of
the course rate behind its bank command (course_rate_lag_s), the follower's ``l1_turn_lead_s``.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass, replace

import numpy as np

from aircraft import airframe_dir
from aircraft.haps.autopilot import HapsAutopilot
from aircraft.haps.gains import HapsGains
from guidance.fixed_wing_follower import FixedWingPlanFollower
from guidance.l1 import L1Guidance
from guidance.mptp.config import MptpConfig
from guidance.mptp.lead_in import held_turn_rate, lead_in
from guidance.mptp.turnmodel import turn_points, written_out
from guidance.mptp.wind import to_ground
from sim.core.constants import STANDARD_GRAVITY
from sim.core.plan import Plan
from sim.core.state import VehicleState
from sim.geodesy import GeoPoint
from sim.jsbsim_plant import InitialConditions, JSBSimPlant
from sim.testbeds.mptp_turn_vertices import corner_cross_track

ORIGIN = GeoPoint(47.0, 8.0, 0.0)
ALT_M, TAS_MPS = 18_000.0, 26.0  # the storm crossing's flight level and airspeed
PLANT_HZ, CONTROL_HZ = 120, 10
LEAD_M = 3000.0  # straight before the first turn [m]
LEG_M = 1500.0  # straight after each turn [m]
TURN_RAD = math.radians(40.0)  # within the MPTP's course_change_max (45 deg)
ACCEPTANCE_M = 10.0  # below the written-out vertices' spacing of both models
REPLAN_INTO_TURN_S = 5.0  # a replan comes this long after the first turn's planned start [s]


@dataclass(frozen=True, slots=True)
class Case:
    """One flight: ``model`` ("approximate" or "simulated"), ``feed_forward`` (the follower gets
    the plan's turn rates), ``l1_period_s`` and ``turn_lead_s`` [s] (None: the airframe's),
    steady ``wind_ne`` (north, east) [m/s], ``straight_m`` [m] flown before the first turn (0:
    the plan turns at its issue, as an MPTP plan's start turn without the lead-in);
    ``replan_turn_rad`` [rad] (+ right; None: no replan) and ``banked_start``: see the module doc."""

    model: str = "simulated"
    feed_forward: bool = True
    l1_period_s: float | None = None
    wind_ne: tuple[float, float] = (0.0, 0.0)
    turn_lead_s: float | None = None
    straight_m: float = LEAD_M
    replan_turn_rad: float | None = None
    banked_start: bool = True


@dataclass(frozen=True, slots=True)
class Flight:
    """A flown case at the control rate: times ``t`` (K,) [s], true horizontal positions ``xy``
    (K, 2) [m], slewed bank command ``bank_cmd`` (K,) [rad], true course (K,) [rad] and true
    airspeed ``tas`` (K,) [m/s]; ``xte`` the signed cross-track [m] at each written-out vertex
    (+ inside the turn, - outside)."""

    t: np.ndarray
    xy: np.ndarray
    bank_cmd: np.ndarray
    course: np.ndarray
    tas: np.ndarray
    xte: np.ndarray


def _states(cfg: MptpConfig, straight_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Air-mass (north, east) states (5, 2) [m] (4 without the straight), their arrival courses
    [rad] and times [s]: north for ``straight_m``, then a TURN_RAD right and a TURN_RAD left
    fly-over turn, each followed by LEG_M of straight, then LEG_M on."""
    pts, courses, times = [np.zeros(2)], [0.0], [0.0]
    if straight_m > 0.0:
        pts, courses, times = pts + [np.array([straight_m, 0.0])], courses + [0.0], times + [straight_m / cfg.tas_mps]
    for sense in (1.0, -1.0, 0.0):
        chi = courses[-1] + sense * TURN_RAD
        end, flown = (
            (pts[-1], np.zeros(1)) if sense == 0.0 else turn_points(pts[-1], courses[-1], sense * TURN_RAD, cfg)
        )
        pts.append(np.asarray(end).reshape(-1, 2)[-1] + LEG_M * np.array([math.cos(chi), math.sin(chi)]))
        courses.append(chi)
        times.append(times[-1] + (float(flown[-1]) + LEG_M) / cfg.tas_mps)
    return np.array(pts), np.array(courses), np.array(times)


def planned(case: Case) -> Plan:
    """The plan of ``case``: the MPTP's written-out turns through _states, mapped to the ground in
    the steady wind at the times of flight; turn rates withheld without feed-forward."""
    cfg = MptpConfig(turn_model=case.model, tas_mps=TAS_MPS)  # type: ignore[arg-type]
    pts, courses, times = _states(cfg, case.straight_m)
    ne, tt, rates = written_out(pts, times, courses, np.zeros(len(pts) - 1, bool), cfg)
    ne = to_ground(ne, tt, np.asarray(case.wind_ne, float), 0.0)
    pos = np.column_stack([ne, np.full(len(ne), -ALT_M)])
    return Plan(0.0, pos, tt, np.full(len(ne), -1), turn_rates=rates if case.feed_forward else None)


def replanned(case: Case, s: VehicleState) -> Plan:
    """The replan of ``case`` from the true state ``s`` (still air): the lead-in of the MPTP
    (``l1_turn_lead_s`` ahead, s's turn rate held), a fly-over turn of ``replan_turn_rad`` from
    s's bank (or wings level), LEG_M straight, LEG_M on; written out with its turn rates."""
    cfg = MptpConfig(turn_model=case.model, tas_mps=TAS_MPS)  # type: ignore[arg-type]
    bank = s.roll if case.banked_start else 0.0
    lead_s = HapsGains.load().l1_turn_lead_s
    lead = lead_in(s.pos_ned[:2], s.t, s.course_rad, held_turn_rate(s.roll, TAS_MPS, cfg.g), TAS_MPS, lead_s)
    turn = float(case.replan_turn_rad or 0.0)
    end, flown = turn_points(lead.p, lead.course, turn, cfg, bank)
    chi = lead.course + turn
    unit = np.array([math.cos(chi), math.sin(chi)])
    pts = np.array([lead.p, end[-1] + LEG_M * unit, end[-1] + 2 * LEG_M * unit])
    times = lead.t + np.r_[0.0, (flown[-1] + LEG_M) / TAS_MPS, (flown[-1] + 2 * LEG_M) / TAS_MPS]
    ne, tt, rates = written_out(pts, times, np.array([lead.course, chi, chi]), np.zeros(2, bool), cfg, bank)
    ne, tt, labels, led = lead.prepend(ne, tt, np.full(len(ne), -1), rates)
    pos = np.column_stack([ne, np.full(len(ne), -ALT_M)])
    return Plan(s.t, pos, tt, labels, turn_rates=led)


def fly(case: Case) -> Flight:
    """Fly ``case`` on JSBSim with truth as the estimate."""
    plant = JSBSimPlant("haps", 1.0 / PLANT_HZ, ORIGIN, airframe_dir("haps"))
    plant.initialise(InitialConditions(GeoPoint(ORIGIN.lat_deg, ORIGIN.lon_deg, ALT_M), tas_mps=TAS_MPS))
    plant.trim()
    wind = np.array([*case.wind_ne, 0.0])
    if wind.any():
        plant.carry_into_wind(wind)
    gains = HapsGains.load()
    if case.l1_period_s is not None:
        gains = replace(gains, l1_period_s=case.l1_period_s)
    if case.turn_lead_s is not None:
        gains = replace(gains, l1_turn_lead_s=case.turn_lead_s)
    ap = HapsAutopilot(gains)
    ap.reset(plant.truth(), throttle=plant["fcs/throttle-cmd-norm[0]"])
    follower = FixedWingPlanFollower(L1Guidance.for_airframe(ap), TAS_MPS, ACCEPTANCE_M, ORIGIN.alt_m)
    plan = planned(case)
    follower.set_plan(plan)
    t_replan = math.inf if case.replan_turn_rad is None else float(plan.times[int(case.straight_m > 0)])
    t_replan += REPLAN_INTO_TURN_S
    dt, rec = 1.0 / CONTROL_HZ, []
    while plant.time < plan.times[-1]:
        s = plant.truth()
        if s.t >= t_replan:
            plan, t_replan = replanned(case, s), math.inf
            follower.set_plan(plan)
        sp, _ = follower.update(s, s.t, dt)
        cmd = ap.update(s, sp, dt)
        plant.set_many(cmd)
        plant.step(PLANT_HZ // CONTROL_HZ)
        rec.append((s.t, s.pos_ned[0], s.pos_ned[1], cmd["ap/roll-cmd-rad"], s.course_rad, s.tas_mps))
    r = np.array(rec)
    xte = corner_cross_track([(plan.t, plan.positions[:, :2], plan.times)], r[:, 0], r[:, 1:3])
    return Flight(r[:, 0], r[:, 1:3], r[:, 3], np.unwrap(r[:, 4]), r[:, 5], xte)


def course_rate_lag_s(flight: Flight, longest_s: float = 3.0) -> float:
    """The lag [s] of the true course rate behind the coordinated-turn rate g tan(bank) / V of the
    slewed bank command: the shift (in control steps, up to ``longest_s``) with the least rms
    difference over the flight."""
    rate = np.gradient(flight.course, flight.t)
    demand = STANDARD_GRAVITY * np.tan(flight.bank_cmd) / flight.tas
    shifts = np.arange(round(longest_s * CONTROL_HZ) + 1)
    n = len(rate) - shifts[-1]
    rms = [np.sqrt(np.mean((rate[k : k + n] - demand[:n]) ** 2)) for k in shifts]
    return float(shifts[int(np.argmin(rms))]) / CONTROL_HZ


def predicted_offset_m(l1_period_s: float, damping: float, radius_m: float, speed_mps: float) -> float:
    """Steady offset d [m] outside an arc of ``radius_m`` [m] of L1 on its chords without
    feed-forward: the root of 4 damping^2 d (R + d) = L1^2 (guidance/l1.py)."""
    l1 = damping * l1_period_s * speed_mps / math.pi
    return 0.5 * (-radius_m + math.sqrt(radius_m**2 + l1 * l1 / (damping * damping)))


CASES = (
    Case(feed_forward=False),
    Case(feed_forward=False, l1_period_s=20.0),
    Case(feed_forward=False, l1_period_s=12.5),
    Case(turn_lead_s=0.0),
    Case(),
    Case(feed_forward=False, wind_ne=(8.0, 0.0)),
    Case(wind_ne=(8.0, 0.0)),
    Case(wind_ne=(0.0, 8.0)),
    Case("approximate", feed_forward=False),
    Case("approximate"),
)


def main(argv: list[str] | None = None) -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args(argv)
    g = HapsGains.load()
    radius = MptpConfig(tas_mps=TAS_MPS).fly_over_radius_m
    cols = ["turn model", "wind N,E [m/s]", "L1 period [s]", "feed-forward, lead [s]", "largest cut [m]"]
    cols += ["largest outside [m]", "steady offset predicted [m]"]
    print("| " + " | ".join(cols) + " |\n|" + "---|" * len(cols))
    for c in CASES:
        x = fly(c).xte
        period = c.l1_period_s or g.l1_period_s
        lead = g.l1_turn_lead_s if c.turn_lead_s is None else c.turn_lead_s
        pred = 0.0 if c.feed_forward else predicted_offset_m(period, g.l1_damping, radius, TAS_MPS)
        row = [
            c.model,
            f"{c.wind_ne[0]:g}, {c.wind_ne[1]:g}",
            f"{period:g}",
            f"yes, {lead:g}" if c.feed_forward else "no",
        ]
        row += [f"{max(x.max(), 0.0):.1f}", f"{max(-x.min(), 0.0):.1f}", f"{pred:.1f}"]
        print("| " + " | ".join(row) + " |", flush=True)
    lag = course_rate_lag_s(fly(Case()))
    print(f"\ncourse-rate lag behind the bank command: {lag:.1f} s (l1_turn_lead_s = {g.l1_turn_lead_s:g} s)")


if __name__ == "__main__":
    main()
