"""HAPS inner loops (``aircraft/haps/systems/attitude_hold.xml``, every 120 Hz step) as transfer
functions of the JSBSim linear model (:mod:`sim.tuning.linearize`), gains as implemented.

Pitch hold::

    elevator = -[ s (kp e - kd q) + ki s / p e ],   e = theta_cmd - theta,  s = gain schedule

Roll hold, with the yaw damper, the aileron-rudder interconnect and the turn feed-forward closed::

    aileron = s (kp e - kd p) + ki s / p e - k_ry (b / 2V) r,        e = phi_cmd - phi
    rudder  = s (kr (r - g cos(theta0) phi / V) - kbeta v / V) - k_ari aileron

Each loop is opened where every gain of its PID acts (at the surface command), so scaling the
PID's three gains together scales the loop by the same factor (what :mod:`sim.tuning.tuner`
uses). The pitch loop is also reported opened at the theta error with its rate damper closed.
A half-step ZOH delay (Pade) stands for the 120 Hz sampling. Frequencies rad/s, angles rad.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import control as ct
import numpy as np

from aircraft.haps.gains import HapsGains
from sim.core.constants import STANDARD_GRAVITY
from sim.jsbsim_plant import JSBSimPlant
from sim.tuning.linearize import LATERAL, LONGITUDINAL, LinearModel
from sim.tuning.loops import S, pade_delay

HAPS_DT = 1.0 / 120.0


@dataclass(frozen=True)
class HapsTrimContext:
    """What the loops need from the trimmed plant besides A and B."""

    sched: float  # gain schedule qbar_ref / qbar (clipped as in the XML)
    tas_mps: float  # true airspeed [m/s]
    theta0_rad: float  # trim pitch [rad]
    bi2vel_s: float  # b / (2 V) [s]
    eas_mps: float  # equivalent airspeed [m/s]

    @classmethod
    def of(cls, plant: JSBSimPlant, gains: HapsGains) -> HapsTrimContext:
        qref = gains.fcs_properties()["ap/qbar-ref-psf"]
        sched = min(max(qref / plant["aero/qbar-psf"], gains.sched_min), gains.sched_max)
        tas = plant["velocities/vt-fps"] * 0.3048
        return cls(sched, tas, plant["attitude/theta-rad"], plant["aero/bi2vel"], plant.truth().eas_mps)


def _tf(sys, k: int):
    return ct.minreal(ct.ss2tf(sys[k, 0]), verbose=False)


def haps_pitch_loops(lm: LinearModel, g: HapsGains, ctx: HapsTrimContext, dt: float = HAPS_DT):
    """(L at elevator, L at theta error, T theta_cmd -> theta) of the HAPS pitch hold."""
    sys = lm.ss(LONGITUDINAL, ["fcs/elevator-cmd-norm"], ["theta", "q"])
    gth, gq = _tf(sys, 0), _tf(sys, 1)
    delay = pade_delay(dt / 2)
    pi = g.kp_pitch + g.ki_pitch / S
    l_el = -ctx.sched * (pi * gth + g.kd_pitch * gq) * delay
    inner = 1 - ctx.sched * g.kd_pitch * gq * delay
    l_th = ct.minreal(-ctx.sched * pi * gth * delay / inner, verbose=False)
    return l_el, l_th, ct.feedback(l_th, 1)


def haps_roll_plant(lm: LinearModel, g: HapsGains, ctx: HapsTrimContext):
    """State space from the roll-PID output [normalised aileron] to (phi [rad], p [rad/s]), with
    the yaw damper, the interconnect and the turn feed-forward closed (module docstring)."""
    a, b = lm.sub(LATERAL, ["fcs/aileron-cmd-norm", "fcs/rudder-cmd-norm"])
    ba, br = b[:, :1], b[:, 1:]
    v = ctx.tas_mps
    # aileron = u + f_a x; rudder = f_r x - k_ari aileron; x = [v, p, r, phi]
    f_a = np.array([[0.0, 0.0, -g.k_roll_yaw * ctx.bi2vel_s, 0.0]])
    f_r = ctx.sched * np.array(
        [[-g.kbeta_yaw / v, 0.0, g.kr_yaw, -g.kr_yaw * STANDARD_GRAVITY * math.cos(ctx.theta0_rad) / v]]
    )
    a_aug = a + ba @ f_a + br @ (f_r - g.k_ari * f_a)
    b_aug = ba - g.k_ari * br
    c = np.zeros((2, 4))
    c[0, LATERAL.index("phi")] = 1.0
    c[1, LATERAL.index("p")] = 1.0
    return ct.ss(a_aug, b_aug, c, np.zeros((2, 1)))


def haps_roll_loops(lm: LinearModel, g: HapsGains, ctx: HapsTrimContext, dt: float = HAPS_DT):
    """(L at aileron, T phi_cmd -> phi) of the HAPS roll hold."""
    plant = haps_roll_plant(lm, g, ctx)
    gphi, gp = _tf(plant, 0), _tf(plant, 1)
    delay = pade_delay(dt / 2)
    pi = g.kp_roll + g.ki_roll / S
    l_ail = ctx.sched * (pi * gphi + g.kd_roll * gp) * delay
    damped = ct.feedback(plant * ct.ss(delay), np.array([[0.0, ctx.sched * g.kd_roll]]))
    return l_ail, ct.feedback(ctx.sched * ct.ss(pi) * damped[0, 0], 1)
