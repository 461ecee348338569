"""Land detection for a multirotor (PX4 ``land_detector``, reduced to its ground-contact test).

The vehicle is declared landed when, continuously for ``LandGains.time_s`` seconds, a descent
is demanded, the collective thrust demand is low (the velocity loop has throttled down because
the ground stops the descent) and the vehicle does not move. Speeds in m/s (NED), thrust as a
fraction of the maximum collective thrust.
"""

from __future__ import annotations

from aircraft.quadrotor.gains import LandGains


class LandDetector:
    """Debounced ground-contact detector."""

    def __init__(self, gains: LandGains, hover_thrust: float):
        self._g = gains
        self._thrust_low = gains.thrust_ratio * hover_thrust
        self._timer = 0.0

    def reset(self) -> None:
        """Forget any contact time accumulated so far."""
        self._timer = 0.0

    def update(self, descent_demanded: bool, vz: float, v_xy: float, thrust: float, dt: float) -> bool:
        """Feed one controller step; True once the contact has lasted ``time_s``.

        ``vz`` is the NED vertical speed [m/s], ``v_xy`` the horizontal speed [m/s], ``thrust``
        the collective thrust demand [fraction], ``dt`` the step [s].
        """
        g = self._g
        if descent_demanded and abs(vz) < g.max_vz and v_xy < g.max_vxy and thrust < self._thrust_low:
            self._timer += dt
        else:
            self._timer = 0.0
        return self._timer >= g.time_s
