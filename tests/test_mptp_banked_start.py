"""The simulated (seed 002 5.3) start turn begins at the aircraft's bank (guidance/mptp/turnmodel.py):
the bank slews at p from the estimate's (limited to the planning bank) to the turn's peak and
rolls out; rolling straight out of it is the smallest turn to the bank's side, a smaller net
turn rolls through wings level. Wings level the tables are the closed form of eqs. 5.62 / 5.68.
HAPS defaults: 26 m/s, planning bank 15 deg, p = 6 deg/s."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import box

from guidance.mptp.config import MptpConfig
from guidance.mptp.planner import MptpPlanner
from guidance.mptp.turnmodel import GRID, STEPS, segment_rates, turn_points, turn_table, turn_to
from sim.core.mission import Mission
from sim.core.plan import Threats
from sim.core.state import VehicleState
from sim.core.threats import StormSnapshot

SIM = MptpConfig(turn_model="simulated")
V, G, P, MU = SIM.tas_mps, SIM.g, SIM.roll_rate_max, SIM.turn_bank_rad
K = G / (V * P)  # course turned per unit of -ln cos(bank) rolled [rad]


def _rolled_out(bank: float) -> float:
    """Course change [rad] of rolling straight out of ``bank`` at p: -g / (V p) ln cos(bank)."""
    return -K * math.log(math.cos(bank))


def _wings_level_table(cfg: MptpConfig) -> np.ndarray:
    """Exit points and lengths (GRID + 1, 3) of the wings-level turns, from the closed form of
    the thesis (roll-in time arccos(exp(-p V dchi / 2 g)) / p below the bank, eq. 5.62; else
    mu / p and the rest held at R, eq. 5.68), integrated with the same trapezoid."""
    v, g, p, mu = cfg.tas_mps, cfg.g, cfg.roll_rate_max, cfg.turn_bank_rad
    theta = np.linspace(0.0, cfg.course_change_max, GRID + 1)
    roll_chi = -2.0 * g / (v * p) * math.log(math.cos(mu))
    t_r = np.where(theta < roll_chi, np.arccos(np.exp(-p * v * theta / (2.0 * g))) / p, mu / p)
    t_hold = np.maximum(theta - roll_chi, 0.0) / (v / cfg.fly_over_radius_m)
    t_total = 2.0 * t_r + t_hold
    t = t_total[:, None] * np.linspace(0.0, 1.0, STEPS + 1)[None, :]

    def rolled(tau):
        return -g / (v * p) * np.log(np.cos(p * np.clip(tau, 0.0, t_r[:, None])))

    held = rolled(t_r[:, None]) + v / cfg.fly_over_radius_m * (t - t_r[:, None])
    chi = np.where(
        t <= t_r[:, None],
        rolled(t),
        np.where(t <= (t_r + t_hold)[:, None], held, theta[:, None] - rolled(t_total[:, None] - t)),
    )
    vel = v * np.stack([np.cos(chi), np.sin(chi)], -1)
    pos = np.sum(0.5 * (t_total / STEPS)[:, None, None] * (vel[:, 1:] + vel[:, :-1]), axis=1)
    return np.column_stack([pos, v * t_total])


@pytest.mark.parametrize(
    "cfg",
    [SIM, SIM.with_(turn_bank_fraction=1.0), SIM.with_(roll_rate_max=math.radians(60.0))],
    ids=["default", "bank limit", "fast roll"],
)
def test_wings_level_tables_are_the_closed_form(cfg):
    tab = turn_table(cfg)
    assert np.column_stack([tab.x, tab.y, tab.length]) == pytest.approx(_wings_level_table(cfg), abs=1e-12)
    assert turn_table(cfg, 0.0) is tab


def _bank_history_turn(theta: float, bank0: float, dt: float = 1e-3) -> tuple[np.ndarray, float]:
    """A turn of ``theta`` [rad] (> 0, to +y) from the bank ``bank0`` (+ towards the turn) by
    brute force: the bank slews at p to a peak b (signed; |b| <= mu, held at +mu as long as
    needed), then back to 0, integrated at ``dt``; the peak is found by bisection on the net
    turn. Returns the exit point (2,) [m] and the flown length [m]."""

    def fly(effort: float) -> tuple[float, np.ndarray, float]:
        peak, hold = min(max(effort, -MU), MU), max(effort - MU, 0.0) / (G * math.tan(MU) / V)
        bank, chi, pos, t, held, phase = bank0, 0.0, np.zeros(2), 0.0, 0.0, "to peak"
        while phase != "done":
            if phase == "hold":
                held += dt
                phase = "out" if held >= hold else phase
            else:
                target = peak if phase == "to peak" else 0.0
                bank += math.copysign(min(P * dt, abs(target - bank)), target - bank)
                if abs(target - bank) < 1e-12:
                    phase = {"to peak": "hold" if hold > 0.0 else "out", "out": "done"}[phase]
            rate = G * math.tan(bank) / V
            pos = pos + V * dt * np.array([math.cos(chi + 0.5 * rate * dt), math.sin(chi + 0.5 * rate * dt)])
            chi += rate * dt
            t += dt
        return chi, pos, V * t

    lo, hi = -MU, MU + 2.0  # the net turn grows with the effort (flat while rolling out of bank0)
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if fly(mid)[0] < theta else (lo, mid)
    _, pos, length = fly(0.5 * (lo + hi))
    return pos, length


@pytest.mark.parametrize(
    ("bank_deg", "turn_deg"),
    [(10.0, 30.0), (10.0, 2.0), (10.0, -30.0), (-15.0, 45.0), (15.0, 5.0), (0.0, 20.0)],
)
def test_a_banked_start_turn_is_its_bank_history(bank_deg, turn_deg):
    """The written-out turn from a bank (+ right) against the brute-force bank history: the exit
    point within 0.5 m and the flown length within 0.2 m (Euler at 1 ms)."""
    pts, along = turn_points(np.zeros(2), 0.0, math.radians(turn_deg), SIM, math.radians(bank_deg))
    side = math.copysign(1.0, turn_deg)
    pos, length = _bank_history_turn(abs(math.radians(turn_deg)), side * math.radians(bank_deg))
    assert np.linalg.norm(pts[-1] - pos * [1.0, side]) < 0.5
    assert along[-1] == pytest.approx(length, abs=0.2)


def test_rolling_straight_out_is_the_smallest_turn_to_the_banks_side():
    """Banked 12 deg right: rolling straight out turns 4.56 deg right in 12 / 6 = 2 s, at a mean
    rate of 4.56 deg / 2 s; twice that turn rolls further in first (longer); half of it rolls
    through wings level to the peak b with -ln cos b = (-ln cos 12 deg - dchi / k) / 2 and back,
    in (12 deg + 2 b) / p; wings level the same half turn only rolls in and out, 2 b0 / p."""
    bank = math.radians(12.0)
    out = _rolled_out(bank)
    assert math.degrees(out) == pytest.approx(4.56, abs=0.005)
    _, along = turn_points(np.zeros(2), 0.0, out, SIM, bank)
    assert along[-1] == pytest.approx(V * bank / P, abs=1e-6)
    assert segment_rates(out, SIM, bank) == pytest.approx([out * P / bank])
    assert turn_points(np.zeros(2), 0.0, 2.0 * out, SIM, bank)[1][-1] > V * bank / P + 1.0
    half = 0.5 * out
    b = math.acos(math.exp(-0.5 * (-math.log(math.cos(bank)) - half / K)))
    assert turn_points(np.zeros(2), 0.0, half, SIM, bank)[1][-1] == pytest.approx(V * (bank + 2 * b) / P, abs=1e-6)
    b0 = math.acos(math.exp(-0.5 * half / K))
    assert turn_points(np.zeros(2), 0.0, half, SIM)[1][-1] == pytest.approx(V * 2 * b0 / P, abs=1e-6)


@settings(max_examples=150, deadline=None)
@given(
    course=st.floats(-math.pi, math.pi),
    bank=st.floats(-0.4, 0.4),
    north=st.floats(-3000, 3000),
    east=st.floats(-3000, 3000),
)
def test_a_banked_turn_to_ends_on_its_target(course, bank, north, east):
    """Every admissible banked start turn, written out (turn_points) and flown straight on for the
    rest of its flown distance, ends on the target on its exit course; a bank over the planning
    bank is the planning bank's turn."""
    target = np.array([[north, east]])
    ok, turn, chi, dist = turn_to(np.zeros(2), course, target, SIM, bank)
    if not ok[0]:
        return
    pts, along = turn_points(np.zeros(2), course, float(turn[0]), SIM, bank)
    straight = dist[0] - along[-1]
    assert straight >= -1e-6 and abs(turn[0]) <= SIM.course_change_max + 1e-9
    end = pts[-1] + straight * np.array([math.cos(chi[0]), math.sin(chi[0])])
    assert np.linalg.norm(end - target[0]) < 1e-2
    capped = math.copysign(min(abs(bank), MU), bank)
    assert turn_to(np.zeros(2), course, target, SIM, capped)[3] == pytest.approx(dist, abs=1e-9)


def test_the_planner_starts_its_first_turn_at_the_estimates_bank():
    """Northbound, the goal 30 km east, banked 12 deg right: the plan's first turn (after the
    lead-in leg at the held rate g tan 12 deg / V) starts near that rate, where the same state
    wings level rolls in from zero; the approximate model (bank set at once) ignores the bank."""
    mission = Mission(np.array([[0.0, 30_000.0, -18_000.0]]), 26.0, 10.0)
    storms = Threats(storms=[StormSnapshot(0.0, (box(-40_000.0, -40_000.0, -38_000.0, -38_000.0),), np.zeros((1, 2)))])
    rates = {}
    for model in ("simulated", "approximate"):
        cfg = MptpConfig(turn_model=model, start_lead_s=1.3)
        for roll in (0.0, math.radians(12.0)):
            est = VehicleState(
                0.0, np.array([0.0, 0.0, -18_000.0]), np.array([26.0, 0.0, 0.0]), np.array([roll, 0.0, 0.0]),
                np.zeros(3), 18_000.0, 47.0, 8.0, 26.0,
            )  # fmt: skip
            plan = MptpPlanner(mission, cfg).plan(est, storms, 0.0)
            rates[model, roll] = plan.turn_rates
    held = G * math.tan(math.radians(12.0)) / V
    banked, level = rates["simulated", math.radians(12.0)], rates["simulated", 0.0]
    assert banked[0] == pytest.approx(held) and level[0] == 0.0  # the lead-in legs
    assert banked[1] > 0.8 * held and 0.0 < level[1] < 0.5 * held
    at_mu = G * math.tan(MU) / V  # the approximate turn's rate, whatever the bank
    assert abs(rates["approximate", math.radians(12.0)][1]) == pytest.approx(at_mu)
    assert abs(rates["approximate", 0.0][1]) == pytest.approx(at_mu)


@pytest.mark.closed_loop
def test_a_replan_in_a_turn_is_flown_closer_from_the_bank():
    """JSBSim HAPS, ideal sensors (sim/testbeds/turn_following.py): 5 s into a 40 deg right turn
    (banked ~16 deg) a new plan turns 30 deg further right, or 30 deg left. From the bank: the
    right turn cut 1.3 m (wings level: 4.8 m, the HAPS already turning inside the modelled
    roll-in); the reversal 26.4 m outside (wings level 49.6 m: the HAPS turns on right while it
    rolls through wings level, which the wings-level model leaves out)."""
    from sim.testbeds.turn_following import Case, fly

    right = [fly(Case(replan_turn_rad=math.radians(30.0), banked_start=b)).xte for b in (True, False)]
    left = [fly(Case(replan_turn_rad=math.radians(-30.0), banked_start=b)).xte for b in (True, False)]
    assert min(len(x) for x in right + left) >= 5
    assert right[0].max() < 2.5 and right[1].max() > 4.0
    assert -left[0].min() < 35.0 and -left[1].min() > 40.0
