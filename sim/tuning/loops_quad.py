"""Quadrotor loops as transfer functions, gains as implemented, cascaded from the inside out.

Rate and attitude (``aircraft/quadrotor/systems/flight-control.xml``, 240 Hz): the plant roll
acceleration per unit roll-torque command, K e^{-d p} / (p (tau p + 1)), is *identified from
JSBSim* (:func:`identify_rotor_axis`: open-loop torque step from the hover trim); the FCS's rate
PID C = kp + ki/p + kd wc p / (p + wc) (D low-passed at wc) gives the rate loop L_rate = C G
(opened at the torque command); the attitude P closes around the rate loop: L_att = kp_att
T_rate / p with T_rate = (kp + ki/p) G / (1 + L_rate) (D on the measurement). A half-step ZOH
delay is added to the identified delay (Pade, 2nd order). Pitch equals roll by symmetry.

Horizontal velocity and position (``aircraft/quadrotor/controller.py``, 60 Hz), about hover, on
the east axis (roll): the acceleration demand a_sp becomes the bank command atan(a_sp / g) and
the bank phi the acceleration g tan(phi), unity gain to first order, so with the attitude loop
closed the plant is v = T_att a_sp / p (body drag neglected: its pole at -0.0x rad/s is far
below the loops). Velocity PID with D on the low-passed measured acceleration (first-order
filter of the controller's discrete low-pass), opened at the acceleration demand::

    L_vel = (kp + ki/p + kd p wf / (p + wf)) T_att e^{-p dt/2} / p

Position P around the closed velocity loop, opened at the velocity demand: L_pos = kp_pos T_vel / p.
Units: rad/s, rad, m/s, m/s^2; the torque unit is a per-motor thrust fraction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import control as ct
import numpy as np
from scipy.optimize import curve_fit

from aircraft.quadrotor.gains import MultirotorGains
from sim.tuning.loops import S, pade_delay

PLANT_DT = 1.0 / 240.0
CONTROL_DT = 1.0 / 60.0


@dataclass
class RotorAxis:
    """Identified axis plant: angular acceleration per unit torque command K [rad/s^2], motor
    time constant tau [s], pure delay [s]."""

    K: float
    tau_s: float
    delay_s: float


def identify_rotor_axis(
    axis: str = "roll", alt_m: float = 100.0, amplitude: float = 0.01, seconds: float = 0.3
) -> RotorAxis:
    """Open-loop step of ``axis`` torque at hover in JSBSim, fitted with
    K (1 - exp(-(t - d)/tau)) on the angular acceleration.

    FCS bypassed as in :mod:`sim.tuning.trim_quad` (motor-health = throttle of each motor);
    motors spun up at the hover trim with the vehicle held (``forces/hold-down``), then released
    and stepped by ``amplitude`` in the FCS's torque unit (per-motor thrust fraction, mixer signs)
    converted to throttle through the FCS's thrust linearisation slope at hover. K is therefore
    per unit of ``ap/<axis>-torque-cmd``."""
    from sim.tuning.trim_quad import (
        ESC_SQRT_WEIGHT,
        MIX,
        bypass_properties,
        hover_thrust_fraction,
        quad_plant,
        quad_trim,
    )

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
    k_axis = ("roll", "pitch", "yaw").index(axis)
    du = MIX[:, 1 + k_axis] * amplitude * slope
    plant.set_many({f"ap/motor-health[{i}]": trim.throttle + du[i] for i in range(4)})
    acc = ("accelerations/pdot-rad_sec2", "accelerations/qdot-rad_sec2", "accelerations/rdot-rad_sec2")[k_axis]
    trace = []
    for _ in range(int(seconds / plant.dt)):
        plant.step()
        trace.append(plant[acc])
    dt = plant.dt
    t = dt * np.arange(1, len(trace) + 1)
    y = np.array(trace) / amplitude

    def model(tt, k, tau, d):
        return k * (1 - np.exp(-np.clip(tt - d, 0, None) / tau))

    (k, tau, d), _ = curve_fit(model, t, y, p0=[y[-1], 0.05, 0.0], bounds=([0, 1e-3, -dt], [np.inf, 1.0, 5 * dt]))
    return RotorAxis(float(k), float(tau), float(d))


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
    g = axis.K / (S * (axis.tau_s * S + 1)) * pade_delay(max(axis.delay_s, 0.0) + dt / 2)
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


def quad_velocity_loops(t_att, g: MultirotorGains, dt: float = CONTROL_DT):
    """(L_vel, T_vel) of the horizontal velocity PID around the closed attitude loop ``t_att``
    (bank command -> bank), module docstring."""
    v = g.velocity
    alpha = dt / (dt + 1.0 / (2 * math.pi * v.d_cutoff_hz))
    wf = -math.log(1.0 - alpha) / dt  # the discrete low-pass's pole as a continuous one [rad/s]
    plant = ct.minreal(t_att * pade_delay(dt / 2) / S, verbose=False)
    pi = v.kp_xy + v.ki_xy / S
    l_vel = ct.minreal((pi + v.kd_xy * wf * S / (S + wf)) * plant, verbose=False)
    return l_vel, ct.minreal(pi * plant / (1 + l_vel), verbose=False)


def quad_position_loops(t_vel, g: MultirotorGains):
    """(L_pos, T_pos) of the horizontal position P around the closed velocity loop ``t_vel``."""
    l_pos = ct.minreal(g.position.kp_xy * t_vel / S, verbose=False)
    return l_pos, ct.feedback(l_pos, 1)


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
    return QuadLoops((l_rate, t_rate), (l_att, t_att), (l_vel, t_vel), quad_position_loops(t_vel, g))
