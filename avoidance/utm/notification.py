"""Position notification (spec §7.3, tab. 6.6) of one UAS, as its peers and the UTM see it.

Frames and units: z-up GCF = ENU [m] from the scenario origin (the reach-set frame), velocity
[m/s], times sim seconds [s], margins [m]. The kinematic part of a peer's notification is its
surveillance track (``sim.core.threats.IntruderTrack``: broadcast with the world's latency,
dropout and noise, ``sim.perception``); the static part (registration, category,
maneuverability, margins) is the registration data filed with the UTM before flight
(:class:`Registration`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from enum import IntEnum

import numpy as np

from sim.core.constants import FT
from sim.core.frames import ned_to_enu
from sim.core.threats import IntruderTrack

FLIGHT_LEVEL_STEP_M = 1000 * FT  # flight-level bands used for the level check [m]
PASSING_BAND_M = 250 * FT  # within this of a level boundary the next level is "passing" (T-UT-5)


class Category(IntEnum):
    """Right-of-way priority (spec §7.3), highest priority first (smaller value wins)."""

    MANNED_IN_DISTRESS = 0
    BALLOON = 1
    GLIDER = 2
    AERIAL_TOWING = 3
    AIRSHIP = 4
    MANNED = 5
    UAS_AUTONOMOUS = 6
    RPAS = 7


class Maneuverability(IntEnum):
    """Maneuverability classes (spec §7.3), highest priority first (smaller value wins)."""

    IMPAIRED_CONTROL = 0
    ALTITUDE_CONTROL_ONLY = 1
    NO_PROPULSION = 2
    LINEAR_PROPULSION = 3
    VTOL = 4


@dataclass(frozen=True, slots=True)
class Margins:
    """Safety margins of one UAS [m] (tab. 6.6); defaults = [R] (universal 5, head-on 5,
    converging 8, overtake 5) for the thesis' 1 m movements, see :meth:`scaled`; ``weather``:
    the soft band around a weather case's body it files (§7.5; the rules' ``weather_margin``)."""

    universal: float = 5.0
    head_on: float = 5.0
    converging: float = 8.0
    overtake: float = 5.0
    weather: float = 5.0

    def scaled(self, unit: float) -> Margins:
        """These margins with the thesis' metre scaled to ``unit`` [m]."""
        return Margins(
            self.universal * unit,
            self.head_on * unit,
            self.converging * unit,
            self.overtake * unit,
            self.weather * unit,
        )


@dataclass(frozen=True, slots=True)
class Registration:
    """Static part of a notification: who the UAS is and what it can do."""

    id: str
    category: Category = Category.UAS_AUTONOMOUS
    maneuverability: Maneuverability = Maneuverability.VTOL
    margins: Margins = field(default_factory=Margins)
    min_cruise: float = 0.0  # [m/s]
    max_cruise: float = np.inf  # [m/s]

    def priority(self) -> tuple[int, int]:
        """Sort key: smaller = higher right-of-way priority (category, then maneuverability)."""
        return int(self.category), int(self.maneuverability)


def flight_levels(altitude_m: float, climb_rate: float = 0.0, climbing: float = 0.5) -> tuple[int, frozenset[int]]:
    """Main flight level (index of the 1000 ft band holding ``altitude_m`` [m]) and the passing
    levels: the neighbour band when within 250 ft of its boundary (T-UT-5) or when climbing /
    descending faster than ``climbing`` [m/s] towards it."""
    main = int(np.floor(altitude_m / FLIGHT_LEVEL_STEP_M))
    lo, hi = main * FLIGHT_LEVEL_STEP_M, (main + 1) * FLIGHT_LEVEL_STEP_M
    passing = set()
    if altitude_m - lo <= PASSING_BAND_M or climb_rate < -climbing:
        passing.add(main - 1)
    if hi - altitude_m <= PASSING_BAND_M or climb_rate > climbing:
        passing.add(main + 1)
    return main, frozenset(passing)


@dataclass(frozen=True, slots=True)
class PositionNotification:
    """One UAS at time ``t``: position / velocity in GCF (ENU) [m, m/s], flight levels and its
    registration; ``trajectory`` (T, 3) GCF at ``trajectory_t`` (T,) [s] is the movement
    prediction (6.187) when known (a filed plan: :meth:`with_intent`), else None (linear
    prediction)."""

    t: float
    registration: Registration
    pos: np.ndarray
    vel: np.ndarray
    cooperative: bool = True
    trajectory: np.ndarray | None = None
    trajectory_t: np.ndarray | None = None

    @property
    def id(self) -> str:
        return self.registration.id

    @property
    def speed(self) -> float:
        return float(np.linalg.norm(self.vel))

    @property
    def levels(self) -> tuple[int, frozenset[int]]:
        return flight_levels(float(self.pos[2]), float(self.vel[2]))

    def shares_level(self, other: PositionNotification) -> bool:
        """Overlapping flight levels (main or passing) of the two UAS (§7.4 step 3)."""
        (m1, p1), (m2, p2) = self.levels, other.levels
        return bool(({m1} | p1) & ({m2} | p2))

    def adjusted(self, t: float) -> PositionNotification:
        """Position moved to time ``t`` (6.182/6.183 corrected): along the movement prediction
        when known, else linearly ``p + v Δt``."""
        if self.trajectory is not None and self.trajectory_t is not None and len(self.trajectory_t) > 1:
            pos = np.array([np.interp(t, self.trajectory_t, self.trajectory[:, k]) for k in range(3)])
        else:
            pos = self.pos + self.vel * (t - self.t)
        return replace(self, t=t, pos=pos)

    def with_intent(
        self, plan: np.ndarray, horizon: float, step: float = 1.0, speed: float | None = None
    ) -> PositionNotification:
        """This notification predicted along its filed mission plan (intent sharing, §7.4 step
        1): ``plan`` (K, 3) GCF [m] = the plan's waypoints not yet reached, the next first; the UAS
        flies from its position to the next waypoint, then leg by leg, at ``speed`` [m/s] (None:
        its current speed), holding at the last one (at its position when none is left); sampled
        every ``step`` [s] over [t, t + horizon]. The authority files a vehicle's plan at its
        cruise speed; a vehicle predicts a peer's filed plan at the peer's tracked speed."""
        plan = np.asarray(plan, float).reshape(-1, 3)
        path = np.vstack([self.pos, plan])
        traj, times = along_path(path, self.speed if speed is None else speed, self.t, step, horizon)
        return replace(self, trajectory=traj, trajectory_t=times)


def along_path(path: np.ndarray, speed: float, t: float, step: float, horizon: float) -> tuple[np.ndarray, np.ndarray]:
    """Positions flown along the polyline ``path`` (K, 3) [m, any Cartesian frame] from its first
    point at ``speed`` [m/s], held at its last; sampled every ``step`` [s] over [t, t + horizon].
    Returns the positions (T, 3) in the path's frame and their times (T,) [s]."""
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    times = t + np.arange(0.0, horizon + step / 2, step)
    flown = np.minimum(speed * (times - t), arc[-1])
    return np.stack([np.interp(flown, arc, path[:, k]) for k in range(3)], axis=1), times


def from_track(track: IntruderTrack, registration: Registration) -> PositionNotification:
    """A peer's notification: its received track (NED) in GCF plus its filed registration."""
    return PositionNotification(
        track.t, registration, ned_to_enu(track.pos_ned), ned_to_enu(track.vel_ned), track.cooperative
    )
