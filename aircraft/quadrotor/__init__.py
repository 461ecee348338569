"""Quadrotor airframe (JSBSim model derived from the F450) and its PX4-style flight controller.

``quadrotor.xml`` + ``engine/`` + ``systems/`` is the JSBSim model (inner loops in the FCS);
``controller.py`` the outer loops, ``gains.toml`` their values, ``README.md`` the model card.
"""

from aircraft.quadrotor.controller import MultirotorController
from aircraft.quadrotor.gains import GainsError, MultirotorGains

__all__ = ["GainsError", "MultirotorController", "MultirotorGains"]
