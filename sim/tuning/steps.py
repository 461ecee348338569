"""Closed-loop step tests in JSBSim: the nonlinear model, inner loops as implemented in the XML,
outer loops by the airframe's own Python controller, with the gains given (default: gains.toml).

- :func:`haps_attitude_step`: HAPS trimmed (JSBSim trim), roll and pitch hold engaged, throttle
  held at trim; the roll or pitch command stepped by ``step`` [rad] at t = 0.
- :func:`haps_tecs_step`: HAPS trimmed, its TECS autopilot in the loop, altitude setpoint ramped
  up (the TECS altitude loop's reference and its rate, as its demand shaping passes them).
- :func:`quad_rate_step`: quadrotor hovering on its FCS; roll-rate command stepped (the attitude
  P is set to ``RATE_PROBE_KP`` and the bank command offset by step / kp, so the rate command is
  the step to within kp x bank, 1e-4 rad/s per rad).
- :func:`quad_attitude_step`: hovering on its FCS; bank command stepped.
- :func:`quad_yaw_rate_step`: hovering on its FCS; yaw-rate command stepped through the FCS's
  yaw-rate feed-forward, the yaw P at 0 (the yaw error wraps, so no offset command can stand for
  a rate).
- :func:`quad_yaw_step`: hovering on its FCS; yaw command stepped.
- :func:`quad_velocity_step`, :func:`quad_position_step`, :func:`quad_climb_rate_step`,
  :func:`quad_altitude_step`: hovering on
  :class:`aircraft.quadrotor.controller.MultirotorController` (60 Hz, truth state); the east or
  up velocity (the other position axes held) or the east or up position stepped.

Each returns a :class:`StepResponse`: time [s] after the step, the response minus its value at
the step (rad, rad/s, m/s or m), and the step size in the same unit.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from aircraft.haps.gains import HapsGains
from aircraft.quadrotor.controller import MultirotorController
from aircraft.quadrotor.gains import MultirotorGains
from sim.core.setpoints import FixedWingSetpoint, MultirotorSetpoint
from sim.jsbsim_plant import JSBSimPlant
from sim.tuning.loops import StepResponse

RATE_PROBE_KP = 1e-4  # [1/s]
TECS_DT = 0.1  # HAPS outer-loop period [s]
M_TO_FT = 1.0 / 0.3048
QUAD_ALT_M = 100.0
_SETTLE_S = 1.0  # hover on the controller before the step [s]


def _record(plant: JSBSimPlant, read: Callable[[], float], seconds: float, step: float, before=None) -> StepResponse:
    """Step ``plant`` for ``seconds``, calling ``before(k)`` ahead of step k; ``read()`` after each."""
    y0 = read()
    n = round(seconds / plant.dt)
    y = np.empty(n)
    for k in range(n):
        if before is not None:
            before(k)
        plant.step()
        y[k] = read() - y0
    return StepResponse(plant.dt * np.arange(1, n + 1), y, step)


def _prop(plant: JSBSimPlant, name: str) -> Callable[[], float]:
    return lambda: plant[name]


def haps_attitude_step(
    axis: str,
    gains: HapsGains | None = None,
    step: float = math.radians(2.0),
    seconds: float = 10.0,
    alt_m: float = 20_000.0,
    tas_mps: float = 29.7,
) -> StepResponse:
    """HAPS roll or pitch hold (``axis``) stepped by ``step`` [rad] from the JSBSim trim."""
    from sim.tuning.trim_haps import jsbsim_trim

    pt, plant = jsbsim_trim(alt_m, tas_mps)
    if plant is None:
        raise RuntimeError(f"HAPS does not trim at {alt_m} m, {tas_mps} m/s: {pt.reason}")
    plant.set_many((gains or HapsGains.load()).fcs_properties())
    prop = {"roll": "attitude/phi-rad", "pitch": "attitude/theta-rad"}[axis]
    cmd = {"ap/roll-cmd-rad": plant["attitude/phi-rad"], "ap/pitch-cmd-rad": plant["attitude/theta-rad"]}
    cmd[f"ap/{axis}-cmd-rad"] += step
    plant.set_many({"ap/engage": 1.0, **cmd})
    return _record(plant, _prop(plant, prop), seconds, step)


def haps_tecs_step(
    gains: HapsGains | None = None,
    seconds: float = 80.0,
    step: float = 2.0,
    rate: float = 0.5,
    alt_m: float = 20_000.0,
    tas_mps: float = 29.7,
) -> StepResponse:
    """HAPS on :class:`aircraft.haps.autopilot.HapsAutopilot` (10 Hz, truth state) from the
    JSBSim trim, altitude setpoint ramped up by ``step`` [m] at ``rate`` [m/s] (below the climb
    limit, so the TECS reference follows it exactly); the altitude change minus that of the same
    flight without the ramp (the trim's residual drift), over ``seconds``."""
    from aircraft.haps.autopilot import HapsAutopilot
    from sim.tuning.trim_haps import jsbsim_trim

    def fly(ramp: float) -> StepResponse:
        pt, plant = jsbsim_trim(alt_m, tas_mps)
        if plant is None:
            raise RuntimeError(f"HAPS does not trim at {alt_m} m, {tas_mps} m/s: {pt.reason}")
        ap = HapsAutopilot(gains or HapsGains.load())
        s0 = plant.truth()
        ap.reset(s0, throttle=plant["fcs/throttle-cmd-norm[0]"])
        every = round(TECS_DT / plant.dt)

        def before(k: int) -> None:
            if k % every == 0:
                sp = FixedWingSetpoint(0.0, s0.alt_msl_m + min(ramp * k * plant.dt, step), s0.tas_mps)
                plant.set_many(ap.update(plant.truth(), sp, every * plant.dt))

        return _record(plant, _prop(plant, "position/h-sl-ft"), seconds, step * M_TO_FT, before)

    flown, still = fly(rate), fly(0.0)
    return StepResponse(flown.t, (flown.y - still.y) / M_TO_FT, step)


def _hover_on_fcs(gains: MultirotorGains) -> JSBSimPlant:
    """Quadrotor at ``QUAD_ALT_M`` with its FCS holding level attitude at hover thrust, motors
    spun up with the vehicle held for 0.5 s, then released."""
    from sim.tuning.trim_quad import hover_thrust_fraction, quad_plant, quad_trim

    plant = quad_plant(QUAD_ALT_M)
    plant.set_many(gains.fcs_properties())
    plant.set_many(
        {
            "ap/armed": 1.0,
            "ap/landed": 0.0,
            "ap/thrust-cmd-norm": hover_thrust_fraction(quad_trim(QUAD_ALT_M, 0.0).throttle),
            "ap/roll-cmd-rad": 0.0,
            "ap/pitch-cmd-rad": 0.0,
            "ap/yaw-cmd-rad": plant["attitude/psi-rad"],
        }
    )
    plant["forces/hold-down"] = 1.0
    plant.step(int(0.5 / plant.dt))
    plant["forces/hold-down"] = 0.0
    return plant


def quad_attitude_step(
    gains: MultirotorGains | None = None, seconds: float = 1.5, step: float = math.radians(5.0)
) -> StepResponse:
    """Bank command stepped by ``step`` [rad] at hover."""
    plant = _hover_on_fcs(gains or MultirotorGains.load())
    plant["ap/roll-cmd-rad"] = plant["attitude/phi-rad"] + step
    return _record(plant, _prop(plant, "attitude/phi-rad"), seconds, step)


def quad_rate_step(gains: MultirotorGains | None = None, seconds: float = 2.0, step: float = 0.5) -> StepResponse:
    """Roll-rate command stepped by ``step`` [rad/s] at hover (module docstring)."""
    g = gains or MultirotorGains.load()
    plant = _hover_on_fcs(replace(g, attitude=replace(g.attitude, kp_roll=RATE_PROBE_KP)))
    plant["ap/roll-cmd-rad"] = plant["attitude/phi-rad"] + step / RATE_PROBE_KP
    return _record(plant, _prop(plant, "velocities/p-rad_sec"), seconds, step)


EAST, UP = np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, -1.0])  # NED unit vectors


def quad_yaw_rate_step(gains: MultirotorGains | None = None, seconds: float = 5.0, step: float = 0.2) -> StepResponse:
    """Yaw-rate command stepped by ``step`` [rad/s] at hover (module docstring)."""
    g = gains or MultirotorGains.load()
    plant = _hover_on_fcs(replace(g, attitude=replace(g.attitude, kp_yaw=0.0)))
    plant["ap/yaw-rate-ff-rps"] = step
    return _record(plant, _prop(plant, "velocities/r-rad_sec"), seconds, step)


def quad_yaw_step(
    gains: MultirotorGains | None = None, seconds: float = 3.0, step: float = math.radians(5.0)
) -> StepResponse:
    """Yaw command stepped by ``step`` [rad] at hover."""
    plant = _hover_on_fcs(gains or MultirotorGains.load())
    plant["ap/yaw-cmd-rad"] = plant["attitude/psi-rad"] + step
    return _record(plant, _prop(plant, "attitude/psi-rad"), seconds, step)


def _controller_step(
    gains: MultirotorGains, seconds: float, step: float, *, velocity: bool, axis: np.ndarray = EAST
) -> StepResponse:
    """Velocity (``velocity``) or position stepped by ``step`` [m/s or m] along ``axis`` (a NED
    unit vector) with the Python controller in the loop, after ``_SETTLE_S`` of hover on it."""
    plant = _hover_on_fcs(gains)
    ctrl = MultirotorController(gains)
    ctrl.reset(plant.truth())
    hold = plant.truth().pos_ned.copy()
    every = round(1.0 / (60.0 * plant.dt))
    dt_c = every * plant.dt

    def control(sp: MultirotorSetpoint):
        def before(k: int) -> None:
            if k % every == 0:
                plant.set_many(ctrl.update(plant.truth(), sp, dt_c))

        return before

    def along() -> float:
        s = plant.truth()
        return float(axis @ (s.vel_ned if velocity else s.pos_ned))

    _record(plant, along, _SETTLE_S, step, control(MultirotorSetpoint(hold.copy())))
    if velocity:
        sp = MultirotorSetpoint(np.where(axis != 0.0, math.nan, hold), step * axis)
    else:
        sp = MultirotorSetpoint(hold + step * axis)
    return _record(plant, along, seconds, step, control(sp))


def quad_velocity_step(gains: MultirotorGains | None = None, seconds: float = 12.0, step: float = 1.0) -> StepResponse:
    """East velocity demand stepped by ``step`` [m/s] at hover (north and down positions held)."""
    return _controller_step(gains or MultirotorGains.load(), seconds, step, velocity=True)


def quad_position_step(gains: MultirotorGains | None = None, seconds: float = 10.0, step: float = 1.0) -> StepResponse:
    """East position demand stepped by ``step`` [m] at hover."""
    return _controller_step(gains or MultirotorGains.load(), seconds, step, velocity=False)


def quad_climb_rate_step(gains: MultirotorGains | None = None, seconds: float = 6.0, step: float = 1.0) -> StepResponse:
    """Up velocity demand stepped by ``step`` [m/s] at hover (north and east positions held)."""
    return _controller_step(gains or MultirotorGains.load(), seconds, step, velocity=True, axis=UP)


def quad_altitude_step(gains: MultirotorGains | None = None, seconds: float = 8.0, step: float = 1.0) -> StepResponse:
    """Up position demand stepped by ``step`` [m] at hover."""
    return _controller_step(gains or MultirotorGains.load(), seconds, step, velocity=False, axis=UP)
