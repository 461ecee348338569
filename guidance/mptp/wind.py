"""The wind the MPTP may know, and its air-mass frame (seed 002, 3.2: future states in wind).

Frames/units: wind is the velocity of the air mass over the ground, (north, east) [m/s]
(``north = 5`` blows towards north); heights are ``up`` = -D of the local-level NED frame [m].
The planner is given a forecast (or an estimate), never the truth.

The planner works in the air-mass frame with the wind w of its flight level, taken steady over
the plan: a point p on the ground at time t is at p - w (t - t_ref) in that frame. There the
aircraft flies at its true airspeed with circular turns of radius R, so the still-air model
(isochrone discs, auxiliary states, fly-by geometry, heuristics) holds exactly; storms move at
their velocity minus w, and a fixed goal becomes a goal moving at -w. A straight leg in the air
frame is a straight leg on the ground (constant ground velocity V u + w), so plan states map back
one by one: p_ground = p_air + w (t - t_ref).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from guidance.mptp.goal import GoalTrack


@dataclass(frozen=True, slots=True)
class WindForecast:
    """Horizontal wind by height and time: ``up_m`` (K,) increasing [m], ``ne_mps`` (K, 2) or
    (H, K, 2) (north, east) [m/s] at the times ``t_s`` (H,) increasing [s] (one table: the
    profile at every time); linear in height and time between the rows and tables, held beyond
    the ends. One row and one table = a steady wind."""

    up_m: np.ndarray
    ne_mps: np.ndarray
    t_s: np.ndarray = field(default_factory=lambda: np.zeros(1))

    def __post_init__(self) -> None:
        up, t = np.atleast_1d(np.asarray(self.up_m, float)), np.atleast_1d(np.asarray(self.t_s, float))
        ne = np.asarray(self.ne_mps, float)
        if (
            ne.size != 2 * len(up) * len(t)
            or not len(up)
            or not np.isfinite(ne).all()
            or np.any(np.diff(up) <= 0)
            or np.any(np.diff(t) <= 0)
        ):
            raise ValueError(
                "wind forecast: expected K increasing heights [m], H increasing times [s] and "
                "H x K (north, east) winds [m/s]"
            )
        object.__setattr__(self, "up_m", up)
        object.__setattr__(self, "ne_mps", ne.reshape(len(t), len(up), 2))
        object.__setattr__(self, "t_s", t)

    @classmethod
    def steady(cls, north: float, east: float) -> WindForecast:
        return cls(np.zeros(1), np.array([[north, east]], float))

    def at(self, up_m: float, t: float = 0.0) -> np.ndarray:
        """Wind (north, east) [m/s] at height ``up_m`` [m] and time ``t`` [s]."""
        by_table = [[np.interp(up_m, self.up_m, table[:, k]) for k in range(2)] for table in self.ne_mps]
        return np.array([np.interp(t, self.t_s, [w[k] for w in by_table]) for k in range(2)])


def to_air(p: np.ndarray, t: np.ndarray | float, wind: np.ndarray, t_ref: float) -> np.ndarray:
    """Ground (north, east) [m] at time(s) t [s] -> the air-mass frame of ``wind`` [m/s]."""
    return np.asarray(p, float) - np.multiply.outer(np.asarray(t, float) - t_ref, wind)


def to_ground(p: np.ndarray, t: np.ndarray | float, wind: np.ndarray, t_ref: float) -> np.ndarray:
    """Air-mass frame (north, east) [m] at time(s) t [s] -> ground."""
    return np.asarray(p, float) + np.multiply.outer(np.asarray(t, float) - t_ref, wind)


def air_goal(goal: GoalTrack, wind: np.ndarray, t_ref: float, t_from: float, t_end: float) -> GoalTrack:
    """A ground goal track as seen in the air-mass frame from ``t_from`` to ``t_end`` [s] (held
    ground points drift at -wind; the track is piecewise linear between its knots and the ends)."""
    knots = goal.times[(goal.times > t_from) & (goal.times < t_end)]
    times = np.concatenate([[t_from], knots, [t_end]])
    return GoalTrack(times, to_air(goal.at(times), times, wind, t_ref))
