"""Fly-over turn models of the auxiliary states (seed 002, 5.2 and 5.3).

Frames/units: (north, east) [m], courses [rad] from north (a right turn increases the course),
times [s]; a turn's own frame has x along the course at its start and y towards its side [m].

A state is flown over: the aircraft arrives on its course, turns there by dchi one way
(|dchi| <= course_change_max) and flies straight on to the next state, which it reaches on the
turn's exit course. A target is admissible when it lies ahead on the exit line of such a turn;
no leg reserves anticipation, the next turn starts at the next state.

Both models turn at the planning bank mu = turn_bank_rad = turn_bank_fraction * bank_max
(config.py), below the follower's bank limit so that it has bank left to catch up.

- "approximate" (5.2): the bank is established at once; the turn is a circular arc of
  R = V^2 / (g tan(mu)) (a Dubins turn, one of the thesis's Fig. 5.2 family).
- "simulated" (5.3, eq. 5.58): chi' = g tan(mu) / V, mu' = +-p at p = roll_rate_max from wings
  level and back (Fig. 5.5: roll-in, constant bank, roll-out). A turn that does not reach
  mu rolls for the half roll time t_r = arccos(exp(-p V dchi / (2 g))) / p each way
  (eq. 5.62); otherwise t_r = mu / p and the bank is held for the rest of the course change
  at R (eq. 5.68). The course is closed-form, the position the trapezoidal integral of V (cos chi,
  sin chi) over STEPS steps (the thesis uses a Taylor series).

In wind the planner works in the air-mass frame (wind.py), where these turns are exact; on the
ground they are the drifted ones.

Each model is tabulated once per aircraft: the exit point (x, y) and flown length of turns of
0..course_change_max at GRID + 1 turn angles. A target's turn is where its offset from the exit
line changes sign, interpolated linearly between grid angles.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from guidance.mptp.config import MptpConfig
from guidance.mptp.turning import wrap

GRID = 360  # turn-angle intervals of a table
STEPS = 400  # integration steps of one turn
SAMPLE_RAD = math.radians(5.0)  # written-out turns: one vertex per this much course change
MIN_STRAIGHT_M = 1.0  # a written-out turn ending closer than this to its state ends at the state


@dataclass(frozen=True, slots=True)
class TurnTable:
    """Turns of ``theta`` (K,) [rad] from (0, 0) on course 0 towards +y: exit points ``x``, ``y``
    (K,) [m] and flown lengths ``length`` (K,) [m]."""

    theta: np.ndarray
    x: np.ndarray
    y: np.ndarray
    length: np.ndarray


def _course_profile(
    theta: np.ndarray, cfg: MptpConfig, s: np.ndarray, bank0: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Duration T (K,) [s] of turns of ``theta`` (K,) [rad] and their course (K, S) [rad] at the
    fractions ``s`` (S,) of T. ``bank0`` [rad]: the simulated turn's bank at its start, signed +
    towards the turn's side, |bank0| <= turn_bank_rad (start_bank)."""
    v, g = cfg.tas_mps, cfg.g
    rate = v / cfg.fly_over_radius_m  # course rate at the planning bank [rad/s]
    theta = np.asarray(theta, float)
    if cfg.turn_model == "approximate":
        t_total = theta / rate
        return t_total, theta[:, None] * s[None, :]
    # The bank goes from bank0 to a peak b at p, is held there, and rolls out to 0 at p. A ramp
    # of the bank from a at the signed rate q turns the course by g / (V q) (F(a + q tau) - F(a)),
    # F(b) = -ln cos b, so the whole turn is k (2 F(b) - F(bank0)) plus the hold (k = g / (V p)).
    # Rolling straight out of bank0 >= 0 turns k F(bank0); a smaller turn rolls through wings
    # level to a peak b < 0 and turns k (F(bank0) - 2 F(b)).
    p, mu = cfg.roll_rate_max, cfg.turn_bank_rad
    k = g / (v * p)

    def f(b):
        return -np.log(np.cos(b))

    f0, f_mu = float(f(bank0)), float(f(mu))
    sign = np.where((bank0 < 0.0) | (theta >= k * f0), 1.0, -1.0)  # the peak's side
    f_peak = 0.5 * f0 + sign * (p * v * theta / (2.0 * g))
    capped = f_peak >= f_mu
    peak = sign * np.where(capped, mu, np.arccos(np.exp(-np.minimum(f_peak, f_mu))))
    t_hold = np.where(capped, np.maximum(theta - k * (2.0 * f_mu - f0), 0.0) / rate, 0.0)
    q1 = np.where(peak >= bank0, p, -p)[:, None]  # signed roll rate of the ramp to the peak
    t1 = np.abs(peak - bank0) / p
    t_total = t1 + t_hold + np.abs(peak) / p
    t = t_total[:, None] * s[None, :]
    t1c, t2c = t1[:, None], (t1 + t_hold)[:, None]
    ramp = g / (v * q1) * (f(bank0 + q1 * np.minimum(t, t1c)) - f0)
    held = ramp + rate * (t - t1c)  # only at the cap (+mu)
    left = np.clip(t_total[:, None] - t, 0.0, (np.abs(peak) / p)[:, None])  # roll-out time left [s]
    rolling_out = theta[:, None] - np.sign(peak)[:, None] * k * f(p * left)
    chi = np.where(t <= t1c, ramp, np.where(t <= t2c, held, rolling_out))
    return t_total, chi


def _integrate(theta: np.ndarray, cfg: MptpConfig, steps: int, bank0: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Turns of ``theta`` (K,) from the bank ``bank0`` [rad] (+ towards the turn): positions
    (K, steps + 1, 2) in the turn frame [m] and lengths (K,) [m]."""
    s = np.linspace(0.0, 1.0, steps + 1)
    t_total, chi = _course_profile(theta, cfg, s, bank0)
    vel = cfg.tas_mps * np.stack([np.cos(chi), np.sin(chi)], -1)
    h = (t_total / steps)[:, None, None]
    pos = np.concatenate([np.zeros((len(theta), 1, 2)), np.cumsum(0.5 * h * (vel[:, 1:] + vel[:, :-1]), axis=1)], 1)
    return pos, cfg.tas_mps * t_total


@functools.lru_cache(maxsize=16)
def _table(key: tuple, bank0: float) -> TurnTable:
    cfg = MptpConfig(**dict(key))
    theta = np.linspace(0.0, cfg.course_change_max, GRID + 1)
    pos, length = _integrate(theta, cfg, STEPS, bank0)
    return TurnTable(theta, pos[:, -1, 0], pos[:, -1, 1], length)


def start_bank(cfg: MptpConfig, bank: float) -> float:
    """The bank [rad] (+ right) a turn of ``cfg``'s model starts from, given the aircraft's
    ``bank``: the simulated model (5.3) starts at the bank, limited to the planning bank
    turn_bank_rad; the approximate one (5.2) sets its bank at once, so starts from 0."""
    if cfg.turn_model != "simulated":
        return 0.0
    return float(np.clip(bank, -cfg.turn_bank_rad, cfg.turn_bank_rad))


def turn_table(cfg: MptpConfig, bank0: float = 0.0) -> TurnTable:
    """The (cached) table of ``cfg``'s turn model (approximate or simulated), its turns starting
    at the bank ``bank0`` [rad] (+ towards the turn's side, see start_bank)."""
    if cfg.turn_model == "simple":
        raise ValueError("turn_table: the simple model has no fly-over turns")
    names = ("tas_mps", "bank_max", "course_change_max", "roll_rate_max", "turn_bank_fraction", "g", "turn_model")
    return _table(tuple((n, getattr(cfg, n)) for n in names), start_bank(cfg, bank0))


def exit_offset_m(cfg: MptpConfig) -> float:
    """Largest distance [m] between a fly-over leg's flown path and its chord: the exit line's
    offset from the turn's start, x sin(dchi) - y cos(dchi), over the turns within the limit
    (a chord of a longer leg comes closer to the exit line)."""
    tab = turn_table(cfg)
    return float(np.max(np.abs(tab.x * np.sin(tab.theta) - tab.y * np.cos(tab.theta))))


def vertex_spacing_m(cfg: MptpConfig) -> float:
    """Lower bound [m] of the step between consecutive written-out vertices (turn_points) of a
    turn of at least SAMPLE_RAD: a turn just past k SAMPLE_RAD splits length(k SAMPLE_RAD) into
    k + 1 steps, so min over the table of length / (floor(turn / SAMPLE_RAD) + 1). A follower
    must switch legs closer to a vertex than this, or it skips the turn's vertices and cuts the
    turn. A turn of less than SAMPLE_RAD is one chord, cut by at most R (1 - cos(SAMPLE_RAD / 2))."""
    tab = turn_table(cfg)
    big = tab.theta >= SAMPLE_RAD - 1e-12
    return float(np.min(tab.length[big] / (np.floor(tab.theta[big] / SAMPLE_RAD + 1e-9) + 1.0)))


def _frame(course: float) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors along ``course`` and to its right [north, east]."""
    return np.array([math.cos(course), math.sin(course)]), np.array([-math.sin(course), math.cos(course)])


def turn_to(
    p: np.ndarray, course: float, targets: np.ndarray, cfg: MptpConfig, bank: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The fly-over turn from p on ``course`` towards each target (N, 2), the turn starting at
    the aircraft's ``bank`` [rad] (+ right; start_bank). Wings level the turn is to the target's
    side; banked, to the side whose turn reaches it with the shorter flight (a turn to the bank's
    side rolls out of it, or through wings level for less than rolling out turns).

    Returns (admissible: a turn within course_change_max points at the target, signed turn
    [rad] (+ = right), course at arrival [rad], flown distance [m] = turn length + straight)."""
    u, n = _frame(course)
    d = np.asarray(targets, float).reshape(-1, 2) - np.asarray(p, float)
    x, lat = d @ u, d @ n
    bank = start_bank(cfg, bank)
    if bank == 0.0:
        side = np.where(lat >= 0.0, 1.0, -1.0)
        ok, theta, dist = _turn_in_table(turn_table(cfg), x, np.abs(lat))
    else:
        right, left = (_turn_in_table(turn_table(cfg, s * bank), x, s * lat) for s in (1.0, -1.0))
        use_left = left[0] & (~right[0] | (left[2] < right[2]))
        side = np.where(use_left, -1.0, 1.0)
        ok, theta, dist = (np.where(use_left, lt, rt) for rt, lt in zip(right, left, strict=True))
    turn = side * theta
    return ok, turn, wrap(course + turn), dist


def _turn_in_table(tab: TurnTable, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The turns of ``tab`` towards +y that point at targets (x, y) (N,) [m] of the turn's frame:
    (admissible, turn [rad] >= 0, flown distance [m]). A target's turn is where its offset from
    the exit line changes sign, ahead of the exit, interpolated between grid angles."""
    c, s = np.cos(tab.theta), np.sin(tab.theta)
    off = c * (y[:, None] - tab.y) - s * (x[:, None] - tab.x)  # target's offset from the exit line
    w = np.clip(off[:, :-1] / np.where(off[:, :-1] == off[:, 1:], 1.0, off[:, :-1] - off[:, 1:]), 0.0, 1.0)
    th = tab.theta[:-1] + w * np.diff(tab.theta)
    ex = tab.x[:-1] + w * np.diff(tab.x)
    ey = tab.y[:-1] + w * np.diff(tab.y)
    ahead = np.cos(th) * (x[:, None] - ex) + np.sin(th) * (y[:, None] - ey)
    valid = (off[:, :-1] >= 0.0) & (off[:, 1:] < 0.0) & (ahead >= 0.0)
    last = np.abs(off[:, -1]) <= 1e-9 * np.maximum(np.hypot(x, y), 1.0)  # exactly on the limit's exit line
    valid = np.column_stack([valid, last & (ahead[:, -1] >= 0.0)])
    k = np.argmax(valid, axis=1)
    ok = np.asarray(valid.any(axis=1))
    rows = np.arange(len(x))
    kk = np.minimum(k, GRID - 1)
    theta = np.where(k == GRID, tab.theta[-1], th[rows, kk])
    length = np.where(k == GRID, tab.length[-1], tab.length[kk] + w[rows, kk] * (tab.length[kk + 1] - tab.length[kk]))
    straight = np.where(
        k == GRID, np.cos(tab.theta[-1]) * (x - tab.x[-1]) + np.sin(tab.theta[-1]) * (y - tab.y[-1]), ahead[rows, kk]
    )
    return ok, theta, length + straight


def aux_states(
    p: np.ndarray, course: float, cfg: MptpConfig, senses: tuple[float, ...], bank: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Auxiliary states of a fly-over state for the turning ``senses`` (+1 right, -1 left): a
    turn of course_change_max from the aircraft's ``bank`` [rad] (+ right), then straight for
    the rest of LD (none when the turn is longer). Returns positions (k, 2) [m], courses (k,)
    [rad] and flown distances (k,) [m]."""
    u, n = _frame(course)
    side = np.asarray(senses, float)
    tabs = [turn_table(cfg, sd * bank) for sd in side]
    ends = np.array([[t.x[-1], t.y[-1], t.length[-1]] for t in tabs]).reshape(-1, 3)
    chi = course + side * cfg.course_change_max
    straight = np.maximum(cfg.leg_m - ends[:, 2], 0.0)
    end = np.asarray(p, float) + np.outer(ends[:, 0], u) + np.outer(side * ends[:, 1], n)
    pts = end + straight[:, None] * np.stack([np.cos(chi), np.sin(chi)], 1)
    return pts, wrap(chi), ends[:, 2] + straight


def turn_points(
    p: np.ndarray, course: float, turn: float, cfg: MptpConfig, bank: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Points along the turn ``turn`` [rad] (+ = right, -0.0 a left one) from p on ``course``,
    from the aircraft's ``bank`` [rad] (+ right), one per SAMPLE_RAD of course change, the start
    excluded and its end included: positions (M, 2) [m] and the distances flown to them (M,) [m]."""
    m = max(1, math.ceil(abs(turn) / SAMPLE_RAD - 1e-9))
    bank0 = math.copysign(1.0, turn) * start_bank(cfg, bank)
    pos, length = _integrate(np.array([abs(turn)]), cfg, m * 40, bank0)
    pick = pos[0, 40::40]
    u, n = _frame(course)
    out = np.asarray(p, float) + np.outer(pick[:, 0], u) + np.outer(math.copysign(1.0, turn) * pick[:, 1], n)
    return out, length[0] * np.arange(1, m + 1) / m


def segment_rates(turn: float, cfg: MptpConfig, bank: float = 0.0) -> np.ndarray:
    """Mean course rate [rad/s] (+ = right) on each of the segments turn_points splits the turn
    ``turn`` [rad] from the aircraft's ``bank`` [rad] into (equal times of flight): the
    segment's course change over its time, the rate g tan(mu) / V of the bank mu the model flies
    there (M,)."""
    m = max(1, math.ceil(abs(turn) / SAMPLE_RAD - 1e-9))
    bank0 = math.copysign(1.0, turn) * start_bank(cfg, bank)
    t_total, chi = _course_profile(np.array([abs(turn)]), cfg, np.linspace(0.0, 1.0, m + 1), bank0)
    return math.copysign(1.0, turn) * np.diff(chi[0]) / (float(t_total[0]) / m)


def written_out(
    positions: np.ndarray,
    times: np.ndarray,
    courses: np.ndarray,
    into_hold: np.ndarray,
    cfg: MptpConfig,
    bank: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The states (N, 2) [m] at ``times`` (N,) [s], arriving on ``courses`` (N,) [rad], with every
    fly-over turn written out as vertices (turn_points) at their times of flight at V, so the
    path a follower tracks is the modelled one; the first turn starts at the aircraft's ``bank``
    [rad] (+ right), every later one wings level. Legs into a holding vertex (``into_hold``
    (N-1,) True) are fly-by orbit legs and stay straight. Returns positions (M, 2), times (M,)
    and the course rate [rad/s] (+ = right) the model flies on the leg from each vertex to the
    next (M,): segment_rates on a turn's segments, 0 on the straights (and the last vertex)."""
    pos, tim, rate = [positions[:1]], [times[:1]], []
    for i in range(len(positions) - 1):
        leg_rates = np.zeros(1)
        b = bank if i == 0 else 0.0
        if not into_hold[i]:
            ok, turn, _, flown = turn_to(positions[i], float(courses[i]), positions[i + 1 : i + 2], cfg, b)
            if ok[0] and (abs(turn[0]) > 1e-6 or start_bank(cfg, b) != 0.0):
                pts, dist = turn_points(positions[i], float(courses[i]), float(turn[0]), cfg, b)
                keep = dist < flown[0] - MIN_STRAIGHT_M  # no zero-length leg into the state
                pos.append(pts[keep])
                tim.append(times[i] + dist[keep] / cfg.tas_mps)
                leg_rates = np.r_[segment_rates(float(turn[0]), cfg, b), 0.0][: int(keep.sum()) + 1]
        rate.append(leg_rates)
        pos.append(positions[i + 1 : i + 2])
        tim.append(times[i + 1 : i + 2])
    rate.append(np.zeros(1))
    return np.vstack(pos), np.concatenate(tim), np.concatenate(rate)
