"""What run metrics measure the vehicles against besides each other: map obstacles, geofences,
scripted traffic, the true storm field, the well-clear and NMAC volumes, the planned duration."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from sim.weather import WeatherService

FT = 0.3048


@dataclass(frozen=True, slots=True)
class MetricsWorld:
    """What metrics measure against besides the vehicles: map obstacles and geofences
    (``sim.core.threats`` types), scripted traffic objects (``sim.traffic.TrafficObject``) and
    the well-clear volume (horizontal radius, vertical half height [m]; default ASTM F3442
    small-UAS well clear, 2000 ft / 250 ft) and the NMAC cylinder (default RTCA DO-365 500 ft /
    100 ft)."""

    obstacles: tuple = ()
    geofences: tuple = ()
    objects: tuple = ()
    well_clear_h_m: float = 2000 * FT
    well_clear_v_m: float = 250 * FT
    weather: WeatherService | None = None  # the true storm field
    nmac_h_m: float = 500 * FT  # near mid-air collision cylinder: horizontal radius [m] ...
    nmac_v_m: float = 100 * FT  # ... and vertical half height [m] (default RTCA DO-365)
    duration_s: float = 0.0  # the run's planned duration [s] (sets how often storms are checked)

    @classmethod
    def from_scenario(cls, scenario, duration_s: float | None = None) -> MetricsWorld:
        """The scenario's world; ``duration_s``: the planned duration if not the scenario's [s]."""
        from sim.environment import geofence, obstacle_prism
        from sim.traffic import TrafficObject
        from sim.weather import WeatherService
        from sim.world import seed_streams, weather_seed

        alt0 = scenario.origin.altitude
        m = scenario.metrics
        weather = (
            WeatherService(scenario.weather, weather_seed(seed_streams(scenario.seed)[2]), scenario.origin_point)
            if scenario.weather is not None
            else None
        )
        return cls(
            tuple(obstacle_prism(o, alt0) for o in scenario.obstacle),
            tuple(geofence(g, alt0) for g in scenario.geofence),
            tuple(TrafficObject(o, scenario.origin_point) for o in scenario.object),
            m.well_clear_horizontal,
            m.well_clear_vertical,
            weather,
            m.nmac_horizontal,
            m.nmac_vertical,
            float(scenario.duration if duration_s is None else duration_s),
        )


# straight flight counts from this long after the last leg capture / carrot stop [s]


EMPTY_WORLD = MetricsWorld()  # no obstacles, fences, objects or storms; default volumes
