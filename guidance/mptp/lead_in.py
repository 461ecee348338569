"""The lead-in: a replan starts its search from the state predicted ``start_lead_s`` ahead.

Frames/units: the air-mass frame (north, east) [m] (wind.py), courses [rad] from north (+ =
right), times [s], turn rates [rad/s] (+ = right).

A plan issued at t whose first turn also began at t could not be led: the fixed-wing follower
feeds a planned turn rate forward ``l1_turn_lead_s`` ahead of the aircraft (the airframe's lag
of the course rate behind its bank command), so a turn that starts at the plan's issue is
entered that lag late and flown wide. The planner therefore predicts where the aircraft will be
after the lead, holding its current turn rate (its bank lags the new command by about the lead),
searches from there, and flies the predicted arc as the plan's first leg.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from guidance.mptp.turning import wrap

STRAIGHT_RATE = 1e-9  # below this turn rate [rad/s] the lead-in is straight


@dataclass(frozen=True, slots=True)
class LeadIn:
    """The state now (``p_now`` (2,) [m] at ``t_now`` [s] on ``course_now`` [rad]), the turn rate
    ``rate`` [rad/s] held over the lead-in, and the predicted start of the search (``p``, ``t``,
    ``course``)."""

    p_now: np.ndarray
    t_now: float
    course_now: float
    rate: float
    p: np.ndarray
    t: float
    course: float

    def prepend(
        self, pts: np.ndarray, times: np.ndarray, labels: np.ndarray, rates: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """A plan's states (``pts`` (N, 2) [m] from the predicted start, ``times`` (N,) [s],
        ``labels`` (N,), turn ``rates`` (N,) [rad/s] or None) with the state now in front, its
        leg flown at the held rate (no vertex added when the lead is zero)."""
        if self.t <= self.t_now:
            return pts, times, labels, rates
        out_rates = None if rates is None else np.r_[self.rate, rates]
        return np.vstack([self.p_now, pts]), np.r_[self.t_now, times], np.r_[-1, labels], out_rates


def lead_in(p_now: np.ndarray, t_now: float, course_now: float, rate: float, speed: float, lead_s: float) -> LeadIn:
    """The lead-in from ``p_now`` (2,) [m] at ``t_now`` [s] on ``course_now`` [rad], turning at
    ``rate`` [rad/s] at ``speed`` [m/s] for ``lead_s`` [s]: the arc's end and exit course."""
    p_now = np.asarray(p_now, float)
    end = course_now + rate * lead_s
    if abs(rate) < STRAIGHT_RATE:
        step = speed * lead_s * np.array([math.cos(course_now), math.sin(course_now)])
    else:
        r = speed / rate
        step = r * np.array([math.sin(end) - math.sin(course_now), math.cos(course_now) - math.cos(end)])
    return LeadIn(p_now, t_now, course_now, rate, p_now + step, t_now + lead_s, float(wrap(end)))


def held_turn_rate(roll_rad: float, speed: float, g: float) -> float:
    """Course rate [rad/s] of a coordinated turn at bank ``roll_rad`` [rad] and true airspeed
    ``speed`` [m/s]: g tan(roll) / V."""
    return g * math.tan(roll_rad) / speed
