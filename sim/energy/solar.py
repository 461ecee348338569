"""Sun and clear-sky irradiance at the vehicle, and the power of a solar array on the wing.

Sun position: pvlib's SPA (``pvlib.solarposition.get_solarposition``) at the vehicle's latitude,
longitude and altitude, with refraction for the ISA pressure and temperature there. Irradiance:
pvlib's Bird clear-sky model (``pvlib.clearsky.bird``) at the vehicle's ISA pressure, with the
water-vapour and aerosol columns above the vehicle falling off exponentially with altitude, and
the extraterrestrial irradiance of the day (``pvlib.irradiance.get_extra_radiation``).

pvlib is evaluated once per ``refresh_s`` (60 s) of sim time, at both ends of the coming window
at the vehicle's current position; sun direction and irradiances are interpolated linearly in
between (the sun moves 0.25 deg/min; a HAPS moves ~2 km/min, 0.02 deg of sun angle).

Simplification: no irradiance while the sun's apparent elevation is below 0 deg, although from
18 km the sun stays visible to -4.3 deg (the grazing path's attenuation is not modelled, and a
wing-level array does not face it). No clouds below or albedo onto the upper surface.

Frames: sun direction as a unit vector in local-level NED (toward the sun); array normal in body
FRD axes, rotated by the vehicle's Euler angles (3-2-1, rad). Units: W/m^2, W, m^2, deg in pvlib.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import datetime, timedelta

import numpy as np
import pandas as pd
import pvlib

from sim.core.frames import euler_to_dcm
from sim.energy.params import ArrayParams, AtmosphereParams
from sim.sensors import isa


@dataclass(frozen=True, slots=True)
class SunSample:
    """Sun as seen from the vehicle: unit vector toward it (NED), apparent elevation [deg],
    direct normal and diffuse horizontal irradiance [W/m^2]."""

    direction_ned: np.ndarray
    elevation_deg: float
    dni_w_m2: float
    dhi_w_m2: float


def sun_direction_ned(elevation_deg: np.ndarray, azimuth_deg: np.ndarray) -> np.ndarray:
    """Unit vectors toward the sun in NED from elevation and azimuth (clockwise from north) [deg]."""
    el, az = np.radians(elevation_deg), np.radians(azimuth_deg)
    return np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), -np.sin(el)], axis=-1)


def clear_sky(
    apparent_zenith_deg: np.ndarray, alt_m: float, dni_extra_w_m2: np.ndarray, atm: AtmosphereParams
) -> tuple[np.ndarray, np.ndarray]:
    """(DNI, DHI) [W/m^2] of pvlib's Bird model at altitude ``alt_m`` [m MSL]; zero with the sun
    at or below the horizon."""
    z = np.asarray(apparent_zenith_deg, float)
    up = z < 90.0
    zc = np.where(up, z, 89.0)
    h = max(alt_m, 0.0)
    am = pvlib.atmosphere.get_relative_airmass(zc)
    aod = atm.aod500 * math.exp(-h / atm.aerosol_scale_height_m)
    bird = pvlib.clearsky.bird(
        zc,
        am,
        aod380=aod,
        aod500=aod,
        precipitable_water=atm.precipitable_water_cm * math.exp(-h / atm.water_scale_height_m),
        ozone=atm.ozone_atm_cm,
        pressure=isa.pressure_at_altitude(h),
        dni_extra=dni_extra_w_m2,
    )
    dni = np.where(up, np.nan_to_num(np.asarray(bird["dni"], float)), 0.0)
    dhi = np.where(up, np.clip(np.nan_to_num(np.asarray(bird["dhi"], float)), 0.0, None), 0.0)
    return dni, dhi


class SunTracker:
    """Sun and irradiance at the vehicle at sim time ``t`` [s] after ``epoch`` (UTC)."""

    def __init__(self, epoch: datetime, atm: AtmosphereParams, refresh_s: float = 60.0):
        if epoch.tzinfo is None:
            raise ValueError("SunTracker: epoch needs a time zone (UTC)")
        self.epoch = epoch
        self.atm = atm
        self.refresh_s = refresh_s
        self._t0 = -math.inf
        self._ends: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None

    def _refresh(
        self, t: float, lat_deg: float, lon_deg: float, alt_m: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        h = max(alt_m, 0.0)
        times = pd.DatetimeIndex(
            [self.epoch + timedelta(seconds=t), self.epoch + timedelta(seconds=t + self.refresh_s)]
        )
        pos = pvlib.solarposition.get_solarposition(
            times,
            lat_deg,
            lon_deg,
            altitude=h,
            pressure=isa.pressure_at_altitude(h),
            temperature=isa.temperature_at_altitude(h) - 273.15,
        )
        zen = pos["apparent_zenith"].to_numpy()
        e0 = np.asarray(pvlib.irradiance.get_extra_radiation(times), float)
        dni, dhi = clear_sky(zen, h, e0, self.atm)
        direction = sun_direction_ned(90.0 - zen, pos["azimuth"].to_numpy())
        self._t0 = t
        self._ends = (direction, 90.0 - zen, dni, dhi)
        return self._ends

    def sample(self, t: float, lat_deg: float, lon_deg: float, alt_m: float) -> SunSample:
        ends = self._ends
        if ends is None or not self._t0 <= t <= self._t0 + self.refresh_s:
            ends = self._refresh(t, lat_deg, lon_deg, alt_m)
        direction, elev, dni, dhi = ends
        w = (t - self._t0) / self.refresh_s
        d = (1.0 - w) * direction[0] + w * direction[1]
        return SunSample(
            d / np.linalg.norm(d),
            float((1.0 - w) * elev[0] + w * elev[1]),
            float((1.0 - w) * dni[0] + w * dni[1]),
            float((1.0 - w) * dhi[0] + w * dhi[1]),
        )


def array_power(array: ArrayParams, sun: SunSample, euler: np.ndarray) -> tuple[float, float]:
    """(electrical power [W] delivered by the array after the MPPT, cosine of the beam's
    incidence on the cells) for the wing at ``euler`` (roll, pitch, yaw [rad]).

    Beam: DNI x max(0, n . s); sky diffuse: isotropic, DHI (1 + cos tilt) / 2 with tilt the
    angle of the cell normal from the zenith (no ground-reflected light on an upper surface)."""
    n = euler_to_dcm(*(float(x) for x in euler)) @ np.asarray(array.normal_body)
    cos_inc = max(0.0, float(n @ sun.direction_ned))
    cos_tilt = -float(n[2])
    irradiance = sun.dni_w_m2 * cos_inc + sun.dhi_w_m2 * max(0.0, 1.0 + cos_tilt) / 2.0
    return irradiance * array.area_m2 * array.cell_efficiency * array.mppt_efficiency, cos_inc
