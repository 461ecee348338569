"""Gain proposal for one loop, and its verification in a closed-loop JSBSim run.

Loop: the quadrotor roll-attitude P (``ap/kp-roll``, 1/s) around the identified rate loop
(:func:`sim.tuning.loops.quad_axis_loops`): L(s) = kp T_rate(s) / s. A single gain sets either
the crossover or the phase margin:

- requested crossover wc [rad/s]:  kp = 1 / |T_rate(j wc) / (j wc)|
- requested phase margin PM [deg]: find w with arg(T_rate(jw)/(jw)) = -180 + PM, then kp as above

Verification: the proposed gain is written to JSBSim's FCS and a roll step is flown
(:func:`sim.tuning.steps.quad_roll_step`); its overshoot is compared with the linear closed loop
and with the second-order estimate from the phase margin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import control as ct
import numpy as np
from scipy.optimize import brentq

from aircraft.quadrotor.gains import MultirotorGains
from sim.tuning.loops import (
    LoopReport,
    RatePid,
    RotorAxis,
    analyse,
    identify_rotor_axis,
    quad_axis_loops,
    second_order_overshoot,
)
from sim.tuning.steps import overshoot_pct, quad_roll_step


@dataclass
class Proposal:
    kp_roll: float
    linear: LoopReport
    jsbsim_overshoot_pct: float | None = None
    second_order_overshoot_pct: float | None = None


def _rate_pid(g: MultirotorGains) -> RatePid:
    r = g.rate
    return RatePid(r.roll.kp, r.roll.ki, r.roll.kd, 2 * math.pi * r.d_cutoff_hz)


def propose_roll_attitude_gain(
    axis: RotorAxis,
    gains: MultirotorGains | None = None,
    crossover_rad_s: float | None = None,
    phase_margin_deg: float | None = None,
) -> Proposal:
    """kp of the roll-attitude loop for a requested crossover *or* phase margin."""
    if (crossover_rad_s is None) == (phase_margin_deg is None):
        raise ValueError("give exactly one of crossover_rad_s, phase_margin_deg")
    g = gains or MultirotorGains.load()
    _, t_rate, _, _ = quad_axis_loops(axis, _rate_pid(g), 1.0)
    h = t_rate / ct.tf("s")

    def resp(w: float) -> complex:
        return complex(h(1j * w))

    if phase_margin_deg is not None:  # then no crossover is given
        target = math.radians(-180.0 + phase_margin_deg)

        def phase(w: float) -> float:
            return float(np.unwrap([np.angle(resp(v)) for v in np.geomspace(1e-3, w, 200)])[-1])

        ws = np.geomspace(0.1, 500, 400)
        ph = np.unwrap([np.angle(resp(v)) for v in ws])
        k = int(np.argmax(ph < target))
        if k == 0:
            raise ValueError(f"phase margin {phase_margin_deg} deg not reachable with this rate loop")
        w_c = float(brentq(lambda w: phase(w) - target, ws[k - 1], ws[k]))
    elif crossover_rad_s is not None:
        w_c = crossover_rad_s
    kp = 1.0 / abs(resp(w_c))
    _, _, l_att, t_att = quad_axis_loops(axis, _rate_pid(g), kp)
    return Proposal(kp, analyse("roll attitude (proposed)", l_att, t_att))


def verify_in_jsbsim(p: Proposal, step_deg: float = 5.0) -> Proposal:
    """Fly a roll step with the proposed gain in JSBSim; fills the overshoot fields."""
    _, y = quad_roll_step(step_deg=step_deg, overrides={"ap/kp-roll": p.kp_roll})
    p.jsbsim_overshoot_pct = overshoot_pct(y, math.radians(step_deg))
    p.second_order_overshoot_pct = second_order_overshoot(p.linear.phase_margin_deg)
    return p


def tune_roll_attitude(
    crossover_rad_s: float | None = None, phase_margin_deg: float | None = None, axis: RotorAxis | None = None
) -> Proposal:
    """Identify the plant (unless given), propose kp, verify in JSBSim."""
    axis = axis or identify_rotor_axis("roll")
    return verify_in_jsbsim(propose_roll_attitude_gain(axis, None, crossover_rad_s, phase_margin_deg))
