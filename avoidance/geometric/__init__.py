"""Geometric candidate-path avoider for multirotors (seed 001, spec avoidance-geometric.md).

``GeometricAvoider`` is the harness planner (NED in/out); ``plan_avoidance`` the core (ENU z-up).
Modules: config, frames, generation, kinematics, threats, collision, costs, normalization,
conflict, avoider, reference, planner (evaluation encounters and the cost sweep: sim.testbeds).
"""

from avoidance.geometric.avoider import AvoidanceResult, Status, plan_avoidance
from avoidance.geometric.config import CostCaps, GeometricConfig, VehicleParams
from avoidance.geometric.planner import GeometricAvoider

__all__ = [
    "AvoidanceResult",
    "CostCaps",
    "GeometricAvoider",
    "GeometricConfig",
    "Status",
    "VehicleParams",
    "plan_avoidance",
]
