"""Quadrotor loops as transfer functions, gains as implemented, cascaded from the inside out.

Rate and attitude (``aircraft/quadrotor/systems/flight-control.xml``, 240 Hz): the plant angular
acceleration per unit torque command is *identified from JSBSim* (:func:`identify_rotor_axis`:
open-loop torque step from the hover trim). Roll and pitch: K e^{-d p} / (tau p + 1), the motor
lag. Yaw: the motors' reaction torque leads: a throttle step changes the motor torque at once
(the current), which then settles to the propeller drag torque as the rpm changes, so
K (a tau p + 1) e^{-d p} / (tau p + 1), with a the initial over the settled acceleration. The
FCS's rate PID C = kp + ki/p + kd wc p / (p + wc) (D low-passed at wc) gives the rate loop
L_rate = C G / p (opened at the torque command); the attitude P closes around the rate loop:
L_att = kp_att T_rate / p with T_rate = (kp + ki/p) G / p / (1 + L_rate) (D on the measurement).
A half-step ZOH delay is added to the identified delay (Pade, 2nd order). Pitch equals roll by
symmetry.

Velocity and position (``aircraft/quadrotor/controller.py``, 60 Hz), about hover. Horizontal,
on the east axis (roll): the acceleration demand a_sp becomes the bank command atan(a_sp / g)
and the bank phi the acceleration g tan(phi), unity gain to first order, so with the attitude
loop closed the plant is v = T_att a_sp / p (body drag neglected: its pole at -0.0x rad/s is far
below the loops). Vertical (up): the demand becomes the collective thrust hover (1 + a_sp / g)
(level), and the collective the acceleration identified like the axes (``collective``:
K e^{-d p} / (tau p + 1) per unit thrust fraction, less D v: the propeller's thrust falls off as
the climb speed v grows, D identified in the climb), so v = K hover / g G_coll e^{-p dt_fcs/2}
a_sp / (p + D). Velocity PID with D on the low-passed measured acceleration (first-order filter
of the controller's discrete low-pass), opened at the acceleration demand::

    L_vel = (kp + ki/p + kd p wf / (p + wf)) plant e^{-p dt/2}

Position P around the closed velocity loop, opened at the velocity demand: L_pos = kp_pos T_vel / p.
Units: rad/s, rad, m/s, m/s^2; the torque and collective unit is a per-motor thrust fraction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import control as ct
import numpy as np
from scipy.optimize import curve_fit

from aircraft.quadrotor.gains import MultirotorGains
from sim.core.constants import STANDARD_GRAVITY
from sim.tuning.loops import S, pade_delay

PLANT_DT = 1.0 / 240.0
CONTROL_DT = 1.0 / 60.0
FT_TO_M = 0.3048
# per identified axis: its column of the mixer (trim_quad.MIX), its JSBSim acceleration and rate
# or speed properties, and their unit in SI (rad; the collective's are ft, down: up positive)
AXES = {
    "roll": (1, "accelerations/pdot-rad_sec2", "velocities/p-rad_sec", 1.0),
    "pitch": (2, "accelerations/qdot-rad_sec2", "velocities/q-rad_sec", 1.0),
    "yaw": (3, "accelerations/rdot-rad_sec2", "velocities/r-rad_sec", 1.0),
    "collective": (0, "accelerations/wdot-ft_sec2", "velocities/v-down-fps", -FT_TO_M),
}
LEADING_AXES = ("yaw",)  # reaction torque: the motor torque leads the settled drag torque
DAMPED_AXES = ("collective",)  # the thrust falls off as the climb speed grows (propeller inflow)
DAMPING_WINDOW_S = (0.5, 2.0)  # after the motor lag: acceleration against climb speed [s]


@dataclass
class RotorAxis:
    """Identified axis plant: acceleration per unit command K [rad/s^2 or m/s^2], motor time
    constant tau [s], pure delay [s], ``lead`` a: the acceleration at the step over the settled
    one (0: first-order lag; the yaw reaction torque's jump), and ``damping`` D [1/s]: the
    acceleration lost per unit of the rate or speed it builds up (0 where not identified)."""

    K: float
    tau_s: float
    delay_s: float
    lead: float = 0.0
    damping: float = 0.0

    def velocity(self, dt: float):
        """Rate or speed per unit command, K (a tau p + 1) / ((tau p + 1) (p + D)), with the
        identified delay and ``dt`` / 2 of ZOH delay (transfer function)."""
        lag = (self.lead * self.tau_s * S + 1) / (self.tau_s * S + 1)
        return self.K * lag * pade_delay(max(self.delay_s, 0.0) + dt / 2) / (S + self.damping)


def identify_rotor_axis(
    axis: str = "roll", alt_m: float = 100.0, amplitude: float = 0.01, seconds: float = 0.3
) -> RotorAxis:
    """Open-loop step of ``axis`` (``roll``, ``pitch``, ``yaw`` torque or ``collective``) at
    hover in JSBSim, fitted with K (1 - (1 - a) exp(-(t - d)/tau)) on the acceleration over the
    first ``seconds`` (a free for the :data:`LEADING_AXES`, 0 for the others). For the
    :data:`DAMPED_AXES` the step goes on, and D is the slope of the acceleration against the
    speed over :data:`DAMPING_WINDOW_S` (least squares).

    FCS bypassed as in :mod:`sim.tuning.trim_quad` (motor-health = throttle of each motor);
    motors spun up at the hover trim with the vehicle held (``forces/hold-down``), then released
    and stepped by ``amplitude`` in the FCS's unit (per-motor thrust fraction, mixer signs)
    converted to throttle through the FCS's thrust linearisation slope at hover. K is therefore
    per unit of ``ap/<axis>-torque-cmd`` or of ``ap/thrust-cmd-norm``."""
    from sim.tuning.trim_quad import (
        ESC_SQRT_WEIGHT,
        MIX,
        bypass_properties,
        hover_thrust_fraction,
        quad_plant,
        quad_trim,
    )

    if axis not in AXES:
        raise ValueError(f"unknown quadrotor axis {axis!r} (known: {', '.join(AXES)})")
    column, acc, speed, to_si = AXES[axis]
    trim = quad_trim(alt_m, 0.0)
    w = ESC_SQRT_WEIGHT  # throttle = w sqrt(f) + (1 - w) f
    f_hover = hover_thrust_fraction(trim.throttle)
    slope = w / (2 * math.sqrt(f_hover)) + (1 - w)  # d throttle / d thrust fraction
    plant = quad_plant(alt_m)
    plant.set_many(bypass_properties())
    plant.set_many({f"ap/motor-health[{i}]": trim.throttle for i in range(4)})
    plant["forces/hold-down"] = 1.0
    plant.step(int(1.0 / plant.dt))
    plant["forces/hold-down"] = 0.0
    du = MIX[:, column] * amplitude * slope
    plant.set_many({f"ap/motor-health[{i}]": trim.throttle + du[i] for i in range(4)})
    n_fit = int(seconds / plant.dt)
    n = max(n_fit, int(DAMPING_WINDOW_S[1] / plant.dt)) if axis in DAMPED_AXES else n_fit
    trace = np.empty((n, 2))
    for i in range(n):
        plant.step()
        trace[i] = plant[acc], plant[speed]
    dt = plant.dt
    t = dt * np.arange(1, n_fit + 1)
    y = trace[:n_fit, 0] * to_si / amplitude

    def model(tt, k, tau, d, a=0.0):
        return k * (1 - (1 - a) * np.exp(-np.clip(tt - d, 0, None) / tau))

    p0: list[float] = [float(y[-1]), 0.05, 0.0]
    lo: list[float] = [0.0, 1e-3, -dt]
    hi: list[float] = [math.inf, 1.0, 5 * dt]
    if axis in LEADING_AXES:
        p0, lo, hi = [*p0, float(y[0] / y[-1])], [*lo, 0.0], [*hi, math.inf]
    fit, _ = curve_fit(model, t, y, p0=p0, bounds=(lo, hi))
    k, tau, d, *lead = (float(v) for v in fit)
    damping = 0.0
    if axis in DAMPED_AXES:
        window = slice(int(DAMPING_WINDOW_S[0] / dt), n)
        slope = np.polyfit(trace[window, 1] * to_si, trace[window, 0] * to_si, 1)[0]
        damping = -float(slope)
    return RotorAxis(k, tau, d, lead[0] if lead else 0.0, damping)


@dataclass
class RatePid:
    """Rate PID gains [torque unit per rad/s, per rad, per rad/s^2] and D low-pass [rad/s]."""

    kp: float
    ki: float
    kd: float
    d_cutoff_rad_s: float


def quad_axis_loops(axis: RotorAxis, pid: RatePid, kp_att: float, dt: float = PLANT_DT):
    """(L_rate, T_rate, L_att, T_att) of one quadrotor axis (rate loop opened at the torque
    command, attitude loop at the rate command)."""
    g = axis.velocity(dt)
    wc = pid.d_cutoff_rad_s
    c = pid.kp + pid.ki / S + pid.kd * wc * S / (S + wc)
    l_rate = c * g
    t_rate = ct.minreal((pid.kp + pid.ki / S) * g / (1 + l_rate), verbose=False)
    l_att = ct.minreal(kp_att * t_rate / S, verbose=False)
    return l_rate, t_rate, l_att, ct.feedback(l_att, 1)


def rate_pid(g: MultirotorGains, axis: str = "roll") -> RatePid:
    """The FCS rate PID of ``axis`` from the gains."""
    r = getattr(g.rate, axis)
    return RatePid(r.kp, r.ki, r.kd, 2 * math.pi * g.rate.d_cutoff_hz)


def _velocity_pid_loops(speed, kp: float, ki: float, kd: float, d_cutoff_hz: float, dt: float = CONTROL_DT):
    """(L_vel, T_vel) of a velocity PID (D on the low-passed measured acceleration) whose
    acceleration demand gives the speed ``speed`` (transfer function), module docstring."""
    alpha = dt / (dt + 1.0 / (2 * math.pi * d_cutoff_hz))
    wf = -math.log(1.0 - alpha) / dt  # the discrete low-pass's pole as a continuous one [rad/s]
    plant = ct.minreal(speed * pade_delay(dt / 2), verbose=False)
    pi = kp + ki / S
    l_vel = ct.minreal((pi + kd * wf * S / (S + wf)) * plant, verbose=False)
    return l_vel, ct.minreal(pi * plant / (1 + l_vel), verbose=False)


def quad_velocity_loops(t_att, g: MultirotorGains, dt: float = CONTROL_DT):
    """(L_vel, T_vel) of the horizontal velocity PID around the closed attitude loop ``t_att``
    (bank command -> bank)."""
    v = g.velocity
    return _velocity_pid_loops(t_att / S, v.kp_xy, v.ki_xy, v.kd_xy, v.d_cutoff_hz, dt)


def quad_position_loops(t_vel, kp: float):
    """(L_pos, T_pos) of a position P ``kp`` [1/s] around the closed velocity loop ``t_vel``."""
    l_pos = ct.minreal(kp * t_vel / S, verbose=False)
    return l_pos, ct.feedback(l_pos, 1)


def quad_yaw_loops(axis: RotorAxis, g: MultirotorGains) -> tuple[tuple, tuple]:
    """((L, T) of the yaw-rate PID, (L, T) of the yaw P) on the identified yaw ``axis``."""
    l_rate, t_rate, l_att, t_att = quad_axis_loops(axis, rate_pid(g, "yaw"), g.attitude.kp_yaw)
    return (l_rate, t_rate), (l_att, t_att)


def quad_vertical_loops(collective: RotorAxis, g: MultirotorGains) -> tuple[tuple, tuple]:
    """((L, T) of the climb-rate PID, (L, T) of the altitude P), up positive, on the identified
    ``collective`` axis: the demand a_sp [m/s^2] sets the collective hover (1 + a_sp / g)."""
    v = g.velocity
    speed = collective.velocity(PLANT_DT) * (g.limits.hover_thrust / STANDARD_GRAVITY)
    l_vz, t_vz = _velocity_pid_loops(speed, v.kp_z, v.ki_z, v.kd_z, v.d_cutoff_hz)
    return (l_vz, t_vz), quad_position_loops(t_vz, g.position.kp_z)


@dataclass(frozen=True)
class QuadLoops:
    """Every horizontal loop of one axis, inside out: (L, T) each."""

    rate: tuple
    attitude: tuple
    velocity: tuple
    position: tuple


def quad_loops(axis: RotorAxis, g: MultirotorGains) -> QuadLoops:
    """The rate, attitude, velocity and position loops of the roll / east axis with ``g``."""
    l_rate, t_rate, l_att, t_att = quad_axis_loops(axis, rate_pid(g), g.attitude.kp_roll)
    l_vel, t_vel = quad_velocity_loops(t_att, g)
    return QuadLoops((l_rate, t_rate), (l_att, t_att), (l_vel, t_vel), quad_position_loops(t_vel, g.position.kp_xy))
