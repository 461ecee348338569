"""Estimators: what controllers, guidance and planners are allowed to see of a vehicle.

``PerfectEstimator`` hands on the plant's true state: the ideal-sensor case, useful for
controller tuning against the model itself. Runs that must close the loop on filtered sensor
data select an estimator that reads sensors only.
"""

from __future__ import annotations

from typing import Protocol

from sim.core.state import VehicleState
from sim.jsbsim_plant import JSBSimPlant


class Estimator(Protocol):
    name: str

    def update(self, t: float) -> VehicleState: ...


class PerfectEstimator:
    """Ideal sensors: the estimate is the truth at the current tick."""

    name = "perfect"

    def __init__(self, plant: JSBSimPlant):
        self._plant = plant

    def update(self, t: float) -> VehicleState:
        return self._plant.truth()
