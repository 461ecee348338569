"""International Standard Atmosphere (1976, to 47 km geopotential) as JSBSim 1.3.3 uses it:
static pressure [Pa] <-> geometric altitude above sea level [m], temperature [K], density
[kg/m^3], and airspeed from pitot differential pressure.

JSBSim's standard atmosphere is defined on *geopotential* altitude ``H = r0 h / (r0 + h)`` with
``r0 = 6 356 766 m``; at 18 km the geometric and geopotential altitudes differ by 51 m, so the
barometer conversion below returns geometric altitude (what the NED frame's D measures).
"""

from __future__ import annotations

import itertools
import math

from sim.core.constants import STANDARD_GRAVITY

R_AIR = 287.05287  # specific gas constant of dry air [J/(kg K)]
P0 = 101_325.0  # sea-level pressure [Pa]
T0 = 288.15  # sea-level temperature [K]
RHO0 = P0 / (R_AIR * T0)  # sea-level density [kg/m^3]
R_GEOPOT = 6_356_766.0  # earth radius of the geopotential conversion [m]

# (base geopotential altitude [m], base temperature [K], lapse rate [K/m])
_LAYERS = (
    (0.0, 288.15, -0.0065),
    (11_000.0, 216.65, 0.0),
    (20_000.0, 216.65, 0.001),
    (32_000.0, 228.65, 0.0028),
    (47_000.0, 270.65, 0.0),
)


def _base_pressures() -> tuple[float, ...]:
    out = [P0]
    for (h0, t0, lapse), (h1, _, _) in itertools.pairwise(_LAYERS):
        out.append(_layer_pressure(out[-1], t0, lapse, h1 - h0))
    return tuple(out)


def _layer_pressure(p_base: float, t_base: float, lapse: float, dh: float) -> float:
    if lapse == 0.0:
        return p_base * math.exp(-STANDARD_GRAVITY * dh / (R_AIR * t_base))
    return p_base * (1.0 + lapse * dh / t_base) ** (-STANDARD_GRAVITY / (R_AIR * lapse))


_P_BASE = _base_pressures()


def _layer_of_pressure(p: float) -> int:
    i = 0
    while i + 1 < len(_LAYERS) and p < _P_BASE[i + 1]:
        i += 1
    return i


def geopotential_of_pressure(p_pa: float) -> float:
    """ISA geopotential altitude [m] at static pressure ``p_pa`` [Pa]."""
    i = _layer_of_pressure(p_pa)
    h0, t0, lapse = _LAYERS[i]
    if lapse == 0.0:
        return h0 - R_AIR * t0 / STANDARD_GRAVITY * math.log(p_pa / _P_BASE[i])
    return h0 + t0 / lapse * ((p_pa / _P_BASE[i]) ** (-R_AIR * lapse / STANDARD_GRAVITY) - 1.0)


def altitude_of_pressure(p_pa: float) -> float:
    """Geometric pressure altitude above sea level [m] of static pressure ``p_pa`` [Pa]."""
    h = geopotential_of_pressure(p_pa)
    return R_GEOPOT * h / (R_GEOPOT - h)


def temperature_of_pressure(p_pa: float) -> float:
    """ISA temperature [K] at static pressure ``p_pa`` [Pa]."""
    i = _layer_of_pressure(p_pa)
    h0, t0, lapse = _LAYERS[i]
    return t0 + lapse * (geopotential_of_pressure(p_pa) - h0)


def pressure_at_altitude(h_m: float) -> float:
    """ISA static pressure [Pa] at geometric altitude ``h_m`` [m] above sea level."""
    hg = R_GEOPOT * h_m / (R_GEOPOT + h_m)
    i = 0
    while i + 1 < len(_LAYERS) and hg >= _LAYERS[i + 1][0]:
        i += 1
    h0, t0, lapse = _LAYERS[i]
    return _layer_pressure(_P_BASE[i], t0, lapse, hg - h0)


def temperature_at_altitude(h_m: float) -> float:
    """ISA temperature [K] at geometric altitude ``h_m`` [m]."""
    return temperature_of_pressure(pressure_at_altitude(h_m))


def density_at_altitude(h_m: float) -> float:
    """ISA density [kg/m^3] at geometric altitude ``h_m`` [m]."""
    return pressure_at_altitude(h_m) / (R_AIR * temperature_at_altitude(h_m))


def height_per_pascal(p_pa: float) -> float:
    """|dh/dp| of the ISA at pressure ``p_pa``: metres of altitude per pascal [m/Pa]."""
    return R_AIR * temperature_of_pressure(p_pa) / (p_pa * STANDARD_GRAVITY)


def airspeeds_from_dp(dp_pa: float, p_static_pa: float) -> tuple[float, float]:
    """(TAS, EAS) [m/s] from pitot differential pressure ``dp_pa`` (incompressible,
    ``dp = rho V^2 / 2``) and static pressure [Pa], air temperature taken from the ISA."""
    dp = max(dp_pa, 0.0)
    rho = p_static_pa / (R_AIR * temperature_of_pressure(p_static_pa))
    return math.sqrt(2.0 * dp / rho), math.sqrt(2.0 * dp / RHO0)
