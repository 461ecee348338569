"""Open-loop transfer functions of the controller loops, as implemented, and their margins.

HAPS pitch-attitude loop (``aircraft/haps/systems/attitude_hold.xml``, 120 Hz)::

    elevator = -[ s (kp e - kd q) + ki s / p e ],   e = theta_cmd - theta,  s = gain schedule

with the plant G_theta(s), G_q(s) from elevator [normalised] to theta [rad] and q [rad/s] of the
JSBSim linear model (:mod:`sim.tuning.linearize`). Two ways to open it:

- ``at elevator``: all feedback broken at the surface, L = -s [(kp + ki/p) G_theta + kd G_q]
  (robustness to gain/phase change in the actuator path);
- ``at theta error``: rate damper closed, L = -s (kp + ki/p) G_theta / (1 - s kd G_q); the
  closed loop theta_cmd -> theta is L / (1 + L).

Quadrotor roll (``aircraft/quadrotor/systems/flight-control.xml``, 240 Hz): the plant roll
acceleration per unit roll-torque command, K e^{-d p} / (p (tau p + 1)), is *identified from
JSBSim* (:func:`identify_rotor_axis`: open-loop torque step from the hover trim);
the FCS's rate PID C = kp + ki/p + kd wc p / (p + wc) (D low-passed at wc) gives the rate loop
L_rate = C G; the attitude P closes around the rate loop: L_att = kp_att T_rate / p with
T_rate = (kp + ki/p) G / (1 + L_rate) (D on the measurement). A half-step ZOH delay is added to
the identified delay (Pade, 2nd order).

Margins from ``control.stability_margins`` (gain margin [dB], phase margin [deg], their
frequencies [rad/s]); bandwidth of the closed loop (-3 dB) [rad/s]; step info of the closed loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import control as ct
import numpy as np
from scipy.optimize import curve_fit

from sim.tuning.linearize import LONGITUDINAL, LinearModel

S = ct.tf("s")


@dataclass
class LoopReport:
    """Margins and closed-loop figures of one loop (frequencies rad/s, angles deg, dB)."""

    name: str
    crossover_rad_s: float
    phase_margin_deg: float
    gain_margin_db: float
    phase_crossover_rad_s: float
    bandwidth_rad_s: float
    overshoot_pct: float
    rise_time_s: float
    settling_time_s: float

    def row(self) -> dict:
        return dict(self.__dict__)


def analyse(name: str, L, T) -> LoopReport:
    """Margins of open loop ``L`` and step/bandwidth figures of closed loop ``T``."""
    gm, pm, _, wpc, wgc, _ = ct.stability_margins(L)
    info = ct.step_info(T, SettlingTimeThreshold=0.02)
    bw = ct.bandwidth(T)
    return LoopReport(
        name,
        float(wgc),
        float(pm),
        20 * math.log10(gm) if np.isfinite(gm) and gm > 0 else math.inf,
        float(wpc),
        float(bw),
        float(info["Overshoot"]),
        float(info["RiseTime"]),
        float(info["SettlingTime"]),
    )


def pade_delay(seconds: float, order: int = 2):
    if seconds <= 0:
        return ct.tf([1.0], [1.0])
    num, den = ct.pade(seconds, order)
    return ct.tf(num, den)


# -- HAPS pitch ---------------------------------------------------------------------------------
@dataclass
class HapsPitchGains:
    kp: float
    ki: float
    kd: float
    sched: float  # gain schedule qbar_ref / qbar at the trim point (clipped as in the XML)


def haps_pitch_plant(lm: LinearModel):
    """(G_theta, G_q): elevator [norm] -> theta [rad], q [rad/s] at the trim of ``lm``."""
    sys = lm.ss(LONGITUDINAL, ["fcs/elevator-cmd-norm"], ["theta", "q"])
    g = ct.ss2tf(sys)
    return ct.minreal(g[0, 0], verbose=False), ct.minreal(g[1, 0], verbose=False)


def haps_pitch_loops(lm: LinearModel, g: HapsPitchGains, dt: float = 1.0 / 120.0):
    """(L at elevator, L at theta error, T theta_cmd -> theta) of the HAPS pitch hold."""
    gth, gq = haps_pitch_plant(lm)
    delay = pade_delay(dt / 2)
    pi = g.kp + g.ki / S
    l_el = -g.sched * (pi * gth + g.kd * gq) * delay
    inner = 1 - g.sched * g.kd * gq * delay
    l_th = ct.minreal(-g.sched * pi * gth * delay / inner, verbose=False)
    return l_el, l_th, ct.feedback(l_th, 1)


# -- quadrotor roll -----------------------------------------------------------------------------
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
    from sim.tuning.trim_quad import MIX, bypass_properties, quad_plant, quad_trim

    trim = quad_trim(alt_m, 0.0)
    w = 0.76  # ap/esc-sqrt-weight: throttle = w sqrt(f) + (1 - w) f
    f_hover = ((-w + math.sqrt(w * w + 4 * (1 - w) * trim.throttle)) / (2 * (1 - w))) ** 2
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
    kp: float
    ki: float
    kd: float
    d_cutoff_rad_s: float


def quad_axis_loops(axis: RotorAxis, pid: RatePid, kp_att: float, dt: float = 1.0 / 240.0):
    """(L_rate, T_rate, L_att, T_att) of one quadrotor axis."""
    g = axis.K / (S * (axis.tau_s * S + 1)) * pade_delay(max(axis.delay_s, 0.0) + dt / 2)
    wc = pid.d_cutoff_rad_s
    c = pid.kp + pid.ki / S + pid.kd * wc * S / (S + wc)
    l_rate = c * g
    t_rate = ct.minreal((pid.kp + pid.ki / S) * g / (1 + l_rate), verbose=False)
    l_att = ct.minreal(kp_att * t_rate / S, verbose=False)
    return l_rate, t_rate, l_att, ct.feedback(l_att, 1)


def second_order_overshoot(pm_deg: float) -> float:
    """Step overshoot [%] of the closed loop of L = wn^2 / (s (s + 2 zeta wn)) with phase margin
    ``pm_deg`` (PM = atan(2 zeta / sqrt(sqrt(1 + 4 zeta^4) - 2 zeta^2)), solved for zeta)."""
    from scipy.optimize import brentq

    pm = math.radians(pm_deg)
    if pm >= math.radians(76.3):  # zeta >= 1: no overshoot
        return 0.0
    zeta = brentq(lambda z: math.atan(2 * z / math.sqrt(math.sqrt(1 + 4 * z**4) - 2 * z * z)) - pm, 1e-6, 0.999)
    return 100.0 * math.exp(-math.pi * zeta / math.sqrt(1 - zeta * zeta))
