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

from dataclasses import dataclass

import numpy as np

from guidance.mptp.goal import GoalTrack


@dataclass(frozen=True, slots=True)
class WindForecast:
    """Horizontal wind by height: ``up_m`` (K,) increasing [m] and ``ne_mps`` (K, 2) (north, east)
    [m/s], linear in between and held beyond the ends; one row = a steady wind."""

    up_m: np.ndarray
    ne_mps: np.ndarray

    def __post_init__(self) -> None:
        up, ne = np.atleast_1d(np.asarray(self.up_m, float)), np.asarray(self.ne_mps, float).reshape(-1, 2)
        if len(up) != len(ne) or not len(up) or not np.isfinite(ne).all() or np.any(np.diff(up) <= 0):
            raise ValueError("wind forecast: expected K increasing heights [m] and K (north, east) winds [m/s]")
        object.__setattr__(self, "up_m", up)
        object.__setattr__(self, "ne_mps", ne)

    @classmethod
    def steady(cls, north: float, east: float) -> WindForecast:
        return cls(np.zeros(1), np.array([[north, east]], float))

    def at(self, up_m: float) -> np.ndarray:
        """Wind (north, east) [m/s] at height ``up_m`` [m]."""
        return np.array([np.interp(up_m, self.up_m, self.ne_mps[:, k]) for k in range(2)])


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
