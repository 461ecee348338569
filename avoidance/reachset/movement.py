"""Movement Automaton (spec §2): the 9 movements, their integrated displacements, prediction
and trajectories, and the segmented automaton for state-dependent manoeuvrability.

Frame: z-up (GCF or LCF, spec §0.1); attitude = (roll, pitch, yaw) [rad] with positive pitch
descending (6.28); positions [m]; times [s].
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import IntEnum
from math import pi, tan

import numpy as np

from avoidance.reachset.config import MovementConfig
from avoidance.reachset.frames import rotation_zyx
from sim.core.constants import STANDARD_GRAVITY


class MovementType(IntEnum):
    """The 9 movements of (6.35), in the enum order of [R]."""

    STRAIGHT = 0
    DOWN = 1
    UP = 2
    LEFT = 3
    RIGHT = 4
    DOWN_LEFT = 5
    DOWN_RIGHT = 6
    UP_LEFT = 7
    UP_RIGHT = 8


# sign of (pitch rate, yaw rate) per movement: Down <=> +pitch, Left <=> +yaw
_RATE_SIGNS = np.array([[0, 0], [1, 0], [-1, 0], [0, 1], [0, -1], [1, 1], [1, -1], [-1, 1], [-1, -1]], float)
N_MOVEMENTS = len(MovementType)


@dataclass(frozen=True, slots=True)
class PrimitiveTable:
    """Displacements of the 9 movements from zero attitude, body-aligned (spec §11.2).

    ``samples_body`` (9, n_sub+1, 3) are the positions at ``k/n_sub`` of the period (sample 0 is
    the start, the last one the end displacement); ``d_att`` (9, 3) = (Δroll, Δpitch, Δyaw)."""

    config: MovementConfig
    samples_body: np.ndarray
    d_att: np.ndarray

    @property
    def d_pos_body(self) -> np.ndarray:
        return self.samples_body[:, -1]

    @property
    def duration(self) -> float:
        return self.config.period

    @property
    def turn_radii(self) -> tuple[float, float]:
        """Smallest horizontal and vertical turn radii R = L / Δangle of a full Left/Right and
        Up/Down movement [m] (inf for a zero increment)."""
        length = self.config.length
        return (
            length / self.config.dyaw if self.config.dyaw > 0 else np.inf,
            length / self.config.dpitch if self.config.dpitch > 0 else np.inf,
        )

    @property
    def pitching(self) -> np.ndarray:
        """(9,) true for the movements that change pitch (cost factor, A-10)."""
        return self.d_att[:, 1] != 0.0


def build_primitive_table(cfg: MovementConfig) -> PrimitiveTable:
    """Integrate the kinematic model (6.28) for one period at constant rates from zero attitude."""
    t_eval = np.linspace(0.0, cfg.period, cfg.n_sub + 1)
    rates = _RATE_SIGNS * np.array([cfg.dpitch, cfg.dyaw]) / cfg.period
    # scipy.integrate (~0.35 s to import) is loaded by the integration, not by the module:
    # scenario validation imports this module's options only.
    from scipy.integrate import solve_ivp

    samples = np.empty((N_MOVEMENTS, cfg.n_sub + 1, 3))
    for m, (q, r) in enumerate(rates):

        def rhs(t, s, q=q, r=r):
            pitch, yaw = s[3], s[4]
            return [
                cfg.speed * np.cos(pitch) * np.cos(yaw),
                cfg.speed * np.cos(pitch) * np.sin(yaw),
                -cfg.speed * np.sin(pitch),
                q,
                r,
            ]

        sol = solve_ivp(rhs, (0.0, cfg.period), np.zeros(5), t_eval=t_eval, rtol=1e-11, atol=1e-12)
        samples[m] = sol.y[:3].T
    d_att = np.zeros((N_MOVEMENTS, 3))
    d_att[:, 1:] = rates * cfg.period
    return PrimitiveTable(cfg, samples, d_att)


def propagate(
    table: PrimitiveTable, pos: np.ndarray, att: np.ndarray, movement: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Apply ``movement`` (N,) to states ``pos`` (N, 3), ``att`` (N, 3): the intra-movement
    samples (N, n_sub+1, 3) (sample 0 = start) and the end attitudes (N, 3) (prediction rule §2.3)."""
    samples = pos[:, None, :] + np.einsum("nij,nsj->nsi", rotation_zyx(att), table.samples_body[movement])
    return samples, att + table.d_att[movement]


@dataclass(frozen=True, slots=True)
class KinState:
    """Discrete MA state (6.33): position [m] and attitude [rad] (z-up), time [s], speed [m/s]."""

    pos: np.ndarray
    att: np.ndarray
    t: float
    v: float


class MovementAutomaton:
    """One movement set: prediction of states and (sampled) trajectories (6.37-6.39)."""

    def __init__(self, table: PrimitiveTable):
        self.table = table

    def apply(self, s: KinState, m: int) -> KinState:
        samples, att = propagate(self.table, s.pos[None], s.att[None], np.array([int(m)]))
        return KinState(samples[0, -1], att[0], s.t + self.table.duration, s.v)

    def trajectory(self, s0: KinState, buffer: Sequence[int], sampled: bool = False) -> np.ndarray:
        """States along the buffer, (n+1, 7) ``[x, y, z, roll, pitch, yaw, t]`` (or every
        intra-movement sample when ``sampled``: (n·n_sub+1, 7))."""
        rows = [np.concatenate([s0.pos, s0.att, [s0.t]])]
        s = s0
        n_sub = self.table.config.n_sub
        for m in buffer:
            if sampled:
                samples, _ = propagate(self.table, s.pos[None], s.att[None], np.array([int(m)]))
                frac = np.arange(1, n_sub + 1) / n_sub
                att = s.att + frac[:, None] * self.table.d_att[int(m)]
                t = s.t + frac * self.table.duration
                rows.extend(np.column_stack([samples[0, 1:], att, t]))
            s = self.apply(s, m)
            if not sampled:
                rows.append(np.concatenate([s.pos, s.att, [s.t]]))
        return np.array(rows)

    @staticmethod
    def project(traj: np.ndarray, t: float) -> np.ndarray:
        """StateProjection (6.11): the state of ``traj`` at time ``t`` (linear in between)."""
        return np.array([np.interp(t, traj[:, 6], traj[:, c]) for c in range(6)] + [t])


# impact states of a KinState by name (spec §2.5, 6.40)
IMPACT_STATES: dict[str, Callable[[KinState], float]] = {"speed": lambda s: s.v, "altitude": lambda s: float(s.pos[2])}


@dataclass(frozen=True, slots=True)
class Segment:
    """One segment of the state space (6.44): half-open interval ``[lower, upper)`` per impact
    state, and the movement set valid inside it."""

    bounds: dict[str, tuple[float, float]]
    movement: MovementConfig

    def contains(self, s: KinState) -> bool:
        return all(lo <= IMPACT_STATES[name](s) < hi for name, (lo, hi) in self.bounds.items())


class SegmentedMovementAutomaton:
    """ActiveMovementAutomaton (6.47) over disjoint segments; tables are built once each."""

    def __init__(self, segments: Sequence[Segment]):
        if not segments:
            raise ValueError("at least one segment")
        self.segments = tuple(segments)
        self.automata = [MovementAutomaton(build_primitive_table(seg.movement)) for seg in self.segments]

    def active_index(self, s: KinState) -> int:
        for i, seg in enumerate(self.segments):
            if seg.contains(s):
                return i
        raise ValueError(f"state outside every segment: speed {s.v}, altitude {s.pos[2]}")

    def active(self, s: KinState) -> MovementAutomaton:
        return self.automata[self.active_index(s)]

    def trajectory(self, s0: KinState, buffer: Sequence[int]) -> np.ndarray:
        """(6.48): each step predicted by the automaton active in the state it starts from."""
        rows = [np.concatenate([s0.pos, s0.att, [s0.t]])]
        s = s0
        for m in buffer:
            s = self.active(s).apply(s, m)
            rows.append(np.concatenate([s.pos, s.att, [s.t]]))
        return np.array(rows)


def thesis_automaton() -> SegmentedMovementAutomaton:
    """The thesis vehicle: one segment, 1 m/s, 1 s, ±15° (spec §2.3)."""
    return SegmentedMovementAutomaton([Segment({}, MovementConfig())])


def speed_band_automaton(
    bands: Sequence[tuple[float, float, float]],
    period: float,
    turn_rate: Callable[[float], float],
    climb_rate: float,
    n_sub: int = 10,
) -> SegmentedMovementAutomaton:
    """Segments over airspeed bands ``(lower, upper, movement speed)`` [m/s]: per band the yaw
    increment is ``turn_rate(speed)·period`` and the pitch increment the flight-path angle of
    ``climb_rate`` [m/s] at that speed (spec §2.7)."""
    segs = []
    for lo, hi, v in bands:
        dpitch = float(np.arctan2(climb_rate, v))
        segs.append(Segment({"speed": (lo, hi)}, MovementConfig(v, period, dpitch, turn_rate(v) * period, n_sub)))
    return SegmentedMovementAutomaton(segs)


def multirotor_automaton(
    cruise: float = 3.0, period: float = 1.0, lateral_accel: float = 2.0, climb_rate: float = 1.0
) -> SegmentedMovementAutomaton:
    """Multirotor (spec §2.7): a slow segment (1 m/s, the thesis set) below 2 m/s and a cruise
    segment; the turn increment is limited by a lateral acceleration [m/s²] (ω = a / v), at most
    15° so that the ±45° grid keeps containing the reach set."""

    def turn(v: float) -> float:
        return min(lateral_accel / v, pi / 12 / period)

    return speed_band_automaton([(0.0, 2.0, 1.0), (2.0, np.inf, cruise)], period, turn, climb_rate)


def haps_automaton(
    cruise: float = 26.0,
    period: float = 1.0,
    bank_max: float = np.radians(20.0),
    climb_rate: float = 1.0,
    g: float = STANDARD_GRAVITY,
) -> SegmentedMovementAutomaton:
    """Fixed-wing HAPS (spec §2.7): ω = g·tan(bank)/v per airspeed band (slow, cruise, fast)."""
    bands = [
        (0.0, 0.9 * cruise, 0.8 * cruise),
        (0.9 * cruise, 1.1 * cruise, cruise),
        (1.1 * cruise, np.inf, 1.2 * cruise),
    ]
    return speed_band_automaton(bands, period, lambda v: g * tan(bank_max) / v, climb_rate)
