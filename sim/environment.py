"""The world around the vehicles: turbulence and gusts (in JSBSim), obstacles and geofences.

The steady wind and its profile are ``sim.wind_field`` (set into JSBSim by the vehicle).
Turbulence is JSBSim's MIL-F-8785C Dryden model ("Milspec", turb-type 3) with the milspec
reference intensities (light / moderate / severe = 15 / 30 / 45 kt at 20 ft with
probability-of-exceedance index 3 / 4 / 6), seeded per vehicle from the scenario seed so runs
repeat bit for bit. Obstacles and geofences become the threat types of ``sim.core.threats`` in
the scenario's local-level NED frame (heights above the origin, ``up = alt - origin alt``).
"""

from __future__ import annotations

import math

from shapely.affinity import rotate
from shapely.geometry import Point, Polygon

from sim import scenario as sc
from sim.core.constants import FT
from sim.core.threats import Geofence, PrismObstacle
from sim.jsbsim_plant import JSBSimPlant

TURBULENCE = {"none": (0.0, 0), "light": (25.0, 3), "moderate": (50.0, 4), "severe": (75.0, 6)}
_MILSPEC = 3


def apply_turbulence(plant: JSBSimPlant, wind: sc.Wind, seed: int) -> None:
    """Turbulence (after the trim); ``seed`` seeds this JSBSim instance's random numbers."""
    plant["simulation/randomseed"] = seed % 2**31
    speed_fps, severity = TURBULENCE[wind.turbulence]
    if severity:
        plant.set_many(
            {
                "atmosphere/turb-type": _MILSPEC,
                "atmosphere/turbulence/milspec/windspeed_at_20ft_AGL-fps": speed_fps,
                "atmosphere/turbulence/milspec/severity": severity,
            }
        )


def start_gust(plant: JSBSimPlant, gust: sc.Gust) -> None:
    """A 1-cosine gust (JSBSim's own profile): ramp in, hold ``duration``, ramp out."""
    vec = (gust.north, gust.east, gust.down)
    mag = math.sqrt(sum(v * v for v in vec))
    if mag == 0.0:
        return
    plant.set_many(
        {
            "atmosphere/cosine-gust/startup-duration-sec": gust.ramp,
            "atmosphere/cosine-gust/steady-duration-sec": gust.duration if gust.duration is not None else 1e9,
            "atmosphere/cosine-gust/end-duration-sec": gust.ramp,
            "atmosphere/cosine-gust/magnitude-ft_sec": mag / FT,
            "atmosphere/cosine-gust/frame": 3,  # local NED
            "atmosphere/cosine-gust/X-velocity-ft_sec": vec[0] / mag,
            "atmosphere/cosine-gust/Y-velocity-ft_sec": vec[1] / mag,
            "atmosphere/cosine-gust/Z-velocity-ft_sec": vec[2] / mag,
            "atmosphere/cosine-gust/start": 1,
        }
    )


def obstacle_prism(o: sc.Obstacle, origin_alt_m: float) -> PrismObstacle:
    """The obstacle as a prism: footprint in (north, east) [m], heights above the origin [m]."""
    if o.shape == "box" and o.length is not None and o.width is not None:
        fp = Polygon(
            [
                (-o.length / 2, -o.width / 2),
                (o.length / 2, -o.width / 2),
                (o.length / 2, o.width / 2),
                (-o.length / 2, o.width / 2),
            ]
        )
        # (north, east) axes: a positive heading turns north towards east, i.e. clockwise
        fp = rotate(fp, -math.degrees(o.heading), origin=(0, 0))
        fp = Polygon([(n + o.north, e + o.east) for n, e in fp.exterior.coords])
    elif o.shape == "cylinder" and o.radius is not None:
        fp = Point(o.north, o.east).buffer(o.radius, quad_segs=16)
    elif o.shape == "polygon" and o.points is not None:
        fp = Polygon(o.points)  # validated simple by the scenario
    else:
        raise ValueError(f"obstacle {o.id!r}: a {o.shape} without its dimensions")
    base = o.base if o.base is not None else origin_alt_m
    return PrismObstacle(o.id, fp, base - origin_alt_m, o.top - origin_alt_m)


def geofence(g: sc.GeofenceSpec, origin_alt_m: float) -> Geofence:
    return Geofence(g.id, Polygon(g.points), g.floor - origin_alt_m, g.ceiling - origin_alt_m, g.keep_in)
