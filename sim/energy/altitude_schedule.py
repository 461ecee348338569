"""Energy management by altitude: store the sun's surplus as height, spend it gliding at night.

A two-state rule on the battery's state of charge, with hysteresis:
- ``up``: from the moment the battery is (nearly) full (SoC >= ``soc_high``) — further solar
  power would be curtailed — the altitude demand is the ``ceiling``;
- ``down``: once SoC has fallen to ``soc_low`` (the sun no longer covers the consumption), the
  altitude demand is the ``floor``, never lower.
TECS stays the one that trades energy: it flies the demand within its climb/sink limits and the
EAS schedule, so at night the aircraft glides down at the sink limit with little throttle and
holds the floor, and by day climbs on surplus power. Altitudes MSL [m].
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class AltitudeSchedule:
    floor_m: float
    ceiling_m: float
    soc_high: float = 0.95
    soc_low: float = 0.90

    def __post_init__(self) -> None:
        if not self.floor_m < self.ceiling_m:
            raise ValueError(f"altitude schedule: floor {self.floor_m} m must be below ceiling {self.ceiling_m} m")
        if not 0.0 <= self.soc_low < self.soc_high <= 1.0:
            raise ValueError(
                f"altitude schedule: need 0 <= soc_low < soc_high <= 1, got {self.soc_low}, {self.soc_high}"
            )


class AltitudeManager:
    """The schedule's state (``up`` or not) and its altitude demand [m MSL]."""

    def __init__(self, schedule: AltitudeSchedule, soc: float):
        self.schedule = schedule
        self.up = soc >= schedule.soc_high

    def altitude(self, soc: float) -> float:
        s = self.schedule
        if soc >= s.soc_high:
            self.up = True
        elif soc <= s.soc_low:
            self.up = False
        return s.ceiling_m if self.up else s.floor_m
