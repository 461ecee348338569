"""What the sensors need of the true world at one instant, and how to read it from JSBSim.

``TruthSample`` = :class:`sim.core.state.VehicleState` (local NED, Euler body FRD->NED, body rates
relative to the earth) + specific force at the CG in body FRD [m/s^2] (non-gravitational force
over mass: about (0, 0, -9.81) in level flight) + static pressure [Pa], air temperature [K],
air density [kg/m^3] and the total wind (steady + turbulence) NED [m/s].

The gyro truth is JSBSim's ``velocities/p,q,r-rad_sec`` (body rates relative to ECEF): the earth
rate (7.3e-5 rad/s) is left out on purpose, because the estimators are flat-earth filters in the
local NED frame (as in mavsim).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.core.constants import FT
from sim.core.state import VehicleState
from sim.jsbsim_plant import JSBSimPlant

PSF = 47.88025898033584  # Pa per lbf/ft^2
SLUG_FT3 = 515.3788183931961  # kg/m^3 per slug/ft^3
RANKINE = 5.0 / 9.0  # K per degree Rankine


@dataclass(frozen=True, slots=True)
class TruthSample:
    """True inputs of the sensor models at sim time ``state.t`` [s] (frames in module doc)."""

    state: VehicleState
    specific_force_body: np.ndarray
    static_pressure_pa: float
    air_temperature_k: float
    air_density_kgm3: float
    wind_ned: np.ndarray

    @property
    def t(self) -> float:
        return self.state.t

    @property
    def dynamic_pressure_pa(self) -> float:
        """Incompressible dynamic pressure rho TAS^2 / 2 [Pa] (what a pitot tube measures)."""
        return 0.5 * self.air_density_kgm3 * self.state.tas_mps**2


# JSBSim 1.3.3 properties (checked with query_property_catalog on c172p): total body forces
# exclude the weight, so force / mass is the specific force at the CG.
_PROPS = (
    "forces/fbx-total-lbs",
    "forces/fby-total-lbs",
    "forces/fbz-total-lbs",
    "inertia/mass-slugs",
    "atmosphere/P-psf",
    "atmosphere/T-R",
    "atmosphere/rho-slugs_ft3",
    "atmosphere/total-wind-north-fps",
    "atmosphere/total-wind-east-fps",
    "atmosphere/total-wind-down-fps",
)
_LBF = 4.4482216152605  # N per lbf
_SLUG = 14.593902937206364  # kg per slug


class TruthSampler:
    """Reads :class:`TruthSample` from one plant (property nodes looked up once)."""

    def __init__(self, plant: JSBSimPlant):
        self._plant = plant
        self._nodes = plant.property_nodes(_PROPS)

    def sample(self, state: VehicleState | None = None) -> TruthSample:
        """Truth now; pass ``state`` if the caller already read ``plant.truth()`` this tick."""
        fx, fy, fz, m, p, t_r, rho, wn, we, wd = (n.get_double_value() for n in self._nodes)
        k = _LBF / (m * _SLUG)
        return TruthSample(
            state=state if state is not None else self._plant.truth(),
            specific_force_body=np.array([fx * k, fy * k, fz * k]),
            static_pressure_pa=p * PSF,
            air_temperature_k=t_r * RANKINE,
            air_density_kgm3=rho * SLUG_FT3,
            wind_ned=np.array([wn * FT, we * FT, wd * FT]),
        )
