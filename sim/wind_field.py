"""The scenario's wind as a field of altitude and time: the steady vector plus a profile.

Wind is the velocity of the air mass, NED [m/s]; altitudes MSL [m]; time [s] since the start.
Profiles are interpolated linearly in altitude (held constant beyond the table's ends) and, for
hourly tables, linearly in time between the two tables around ``t`` (held beyond the ends).

``STANDARD_PROFILES["midlatitude_jet"]`` is a westerly profile (blowing towards east) with its
maximum at 11-12 km and its minimum at 19-21 km: the shape NASA RP-1044 (T. W. Strganac, *Wind
study for high altitude platform design*, 1979) reports from 20+ years of rawinsondes (jet
maximum near the 200 mb level, minimum between 70 and 50 mb). The speeds are round
representative values chosen for this project, not digitised from the report; give measured
data as ``[[wind.levels]]``.
"""

from __future__ import annotations

import numpy as np

from sim import scenario as sc

# altitude MSL [m], wind towards east [m/s]
STANDARD_PROFILES: dict[str, tuple[tuple[float, float], ...]] = {
    "midlatitude_jet": (
        (0.0, 5.0),
        (2000.0, 10.0),
        (5000.0, 18.0),
        (8000.0, 28.0),
        (11000.0, 35.0),
        (12000.0, 35.0),
        (14000.0, 25.0),
        (16000.0, 15.0),
        (18000.0, 8.0),
        (20000.0, 5.0),
        (22000.0, 6.0),
        (25000.0, 10.0),
        (30000.0, 15.0),
    ),
}


class _Table:
    """Horizontal wind against altitude: ``alt`` [m] increasing, ``ne`` (n, 2) [m/s]."""

    def __init__(self, alt: np.ndarray, ne: np.ndarray):
        self.alt = alt
        self.ne = ne

    @classmethod
    def of(cls, levels: list[sc.WindLevel]) -> _Table:
        return cls(np.array([lv.altitude for lv in levels]), np.array([[lv.north, lv.east] for lv in levels]))

    def at(self, alt_m: float) -> tuple[float, float]:
        return (float(np.interp(alt_m, self.alt, self.ne[:, 0])), float(np.interp(alt_m, self.alt, self.ne[:, 1])))

    def max_shear(self) -> float:
        """Largest |d wind / d altitude| of the table [1/s]."""
        if len(self.alt) < 2:
            return 0.0
        return float(np.max(np.linalg.norm(np.diff(self.ne, axis=0), axis=1) / np.diff(self.alt)))


class WindField:
    """``at(alt_m, t)``: the wind NED [m/s] at altitude ``alt_m`` [m MSL] and time ``t`` [s]."""

    def __init__(self, wind: sc.Wind):
        self.steady = np.array([wind.north, wind.east, wind.down])
        self.times = np.array([h.time for h in wind.hours])
        if wind.hours:
            self.tables = [_Table.of(h.levels) for h in wind.hours]
        elif wind.levels:
            self.tables = [_Table.of(wind.levels)]
        elif wind.standard is not None:
            prof = np.array(STANDARD_PROFILES[wind.standard])
            self.tables = [_Table(prof[:, 0], np.column_stack([np.zeros(len(prof)), prof[:, 1]]))]
        else:
            self.tables = []

    @property
    def varies(self) -> bool:
        """True when the wind depends on altitude or time (it must follow the vehicle)."""
        return bool(self.tables)

    def max_shear(self) -> float:
        """Largest vertical shear of the profile [1/s]: the wind error of a vehicle climbing at
        ``v`` [m/s] whose wind is refreshed every ``dt`` [s] is at most ``max_shear * v * dt``."""
        return max((tb.max_shear() for tb in self.tables), default=0.0)

    def forecast_rows(self, origin_alt_m: float) -> tuple[tuple[float, float, float, float], ...]:
        """The profile as a planner's forecast: rows (t [s], up [m above ``origin_alt_m``], north,
        east [m/s]), for each table's time (0 for a single table) at the union of the tables'
        altitudes, ordered by time then height (steady wind included; a copy, not this object):
        linear between the rows in height and time, it gives :meth:`at` everywhere. Empty when
        the wind does not vary."""
        if not self.tables:
            return ()
        alts = np.unique(np.concatenate([tb.alt for tb in self.tables]))
        times = self.times if len(self.times) else np.zeros(1)
        rows = []
        for t in times:
            for a in alts:
                north, east, _ = self.at(float(a), float(t))
                rows.append((float(t), float(a - origin_alt_m), float(north), float(east)))
        return tuple(rows)

    def at(self, alt_m: float, t: float) -> np.ndarray:
        if not self.tables:
            return self.steady
        if len(self.tables) == 1 or t <= self.times[0]:
            n, e = self.tables[0].at(alt_m)
        elif t >= self.times[-1]:
            n, e = self.tables[-1].at(alt_m)
        else:
            k = int(np.searchsorted(self.times, t, side="right")) - 1
            w = (t - self.times[k]) / (self.times[k + 1] - self.times[k])
            (n0, e0), (n1, e1) = self.tables[k].at(alt_m), self.tables[k + 1].at(alt_m)
            n, e = n0 + w * (n1 - n0), e0 + w * (e1 - e0)
        return self.steady + np.array([n, e, 0.0])
