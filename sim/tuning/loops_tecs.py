"""HAPS TECS loops (``aircraft/haps/autopilot.py``, 10 Hz) linearised about a level trim, with
the pitch hold (:mod:`sim.tuning.loops_haps`) closed underneath.

Plant: the JSBSim linear model's longitudinal states [u, w, q, theta, h] plus a thrust lag: the
linear model holds the propeller rpm, so throttle acts through a first-order lag T' = (thr - T) /
tau on the settled-rpm throttle column ``b_thr`` of the state derivatives. Both are measured in
JSBSim by :func:`thrust_lag` (throttle stepped with the body state held, propellers stepped at
the plant's dt): at 20 km, 29.7 m/s, tau = 3.6 s, du/dt = 1.11 m/s^2 per unit throttle.

TECS, small perturbations about trim (speed weight w, v the airspeed, V0 its trim value), its
demand-shaping clamps inactive (small steps): with the airspeed low-pass F = 1 / (T_tas p + 1),
v_f = F v, vdot = p F v / (T_vdot p + 1),
``hdot_dem = (h_ref - h) / T_h + h_ref'``, ``vdot_dem = -v_f / T_v``::

    throttle = k [ dP_ff/dv v_f + STE'_dem + thr_damp (STE'_dem - g hdot - V0 vdot)
                   + thr_integ / p (g (h_ref - h) - V0 v_f) ],      k = m / (eta P_max)
    pitch    = [ SEB'_dem + pitch_damp (SEB'_dem - (2-w) g hdot + w V0 vdot)
                   + pitch_integ / p ((2-w) g (h_ref - h) + w V0 v_f) ] / (g V0)

with STE'_dem = g hdot_dem + V0 vdot_dem and SEB'_dem = (2-w) g hdot_dem - w V0 vdot_dem. The
10 Hz outputs carry a half-step delay (Pade) and the 120 Hz elevator another.

Loops: ``tecs pitch`` opened at the pitch command (throttle channel closed) and ``tecs
throttle`` opened at the throttle (pitch channel closed); closed loop: altitude reference ->
altitude (inputs h_ref [m] and its rate h_ref' [m/s], as the autopilot's reference shaping
produces them). These loops are not single-factor loops (the demand terms close the loop too),
so the gain helper does not tune them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import control as ct
import numpy as np

from aircraft.haps.autopilot import HapsAutopilot
from aircraft.haps.gains import HapsGains
from sim.core.constants import STANDARD_GRAVITY
from sim.jsbsim_plant import JSBSimPlant
from sim.tuning.evaluator import JSBSimEvaluator
from sim.tuning.linearize import LinearModel
from sim.tuning.loops import S, pade_delay
from sim.tuning.loops_haps import HAPS_DT, HapsTrimContext

TECS_DT = 0.1  # [s]
_STATES = ("u", "w", "q", "theta", "h")
_THROTTLES = ("fcs/throttle-cmd-norm[0]", "fcs/throttle-cmd-norm[1]")


@dataclass(frozen=True)
class ThrustLag:
    """State-derivative column per unit throttle at settled rpm (SI, ``STATE_NAMES`` order) and
    the rpm time constant [s]."""

    b_thr: np.ndarray
    tau_s: float


def thrust_lag(plant: JSBSimPlant, du: float = 0.02) -> ThrustLag:
    """Throttle step of ``du`` at the plant's current (trim) state, body state held: the settled
    change of the state derivatives per unit throttle, and the time to 63 % of the settled thrust
    change. The plant is left settled at its original throttle."""
    ev = JSBSimEvaluator(plant)
    x0 = ev.read_state()
    u0 = plant[_THROTTLES[0]]
    thrust = "propulsion/engine[0]/thrust-lbs"
    ev.settle_engines(x0, rtol=1e-9)
    d0, t0 = ev.derivatives(x0), plant[thrust]
    _, trace = ev.settle_engines(x0, dict.fromkeys(_THROTTLES, u0 + du), rtol=1e-9, trace=thrust)
    d1 = ev.derivatives(x0)
    frac = (np.array(trace) - t0) / (trace[-1] - t0)
    tau = plant.dt * (int(np.argmax(frac >= 1.0 - math.exp(-1.0))) + 1)
    ev.settle_engines(x0, dict.fromkeys(_THROTTLES, u0), rtol=1e-9)
    return ThrustLag((d1 - d0) / du, tau)


def _plant(lm: LinearModel, lag: ThrustLag) -> ct.StateSpace:
    """Inputs [elevator, throttle]; outputs [theta, q, h, hdot, v]; states [u, w, q, theta, h, T]."""
    idx = [lm.states.index(s) for s in _STATES]
    a5 = lm.A[np.ix_(idx, idx)]
    b_el = lm.B[idx, lm.inputs.index("fcs/elevator-cmd-norm")]
    a = np.zeros((6, 6))
    a[:5, :5] = a5
    a[:5, 5] = lag.b_thr[idx]
    a[5, 5] = -1.0 / lag.tau_s
    b = np.zeros((6, 2))
    b[:5, 0] = b_el
    b[5, 1] = 1.0 / lag.tau_s
    u0, w0 = lm.x0[lm.states.index("u")], lm.x0[lm.states.index("w")]
    v0 = math.hypot(u0, w0)
    c = np.zeros((5, 6))
    c[0, 3] = c[1, 2] = c[2, 4] = 1.0
    c[3, :] = a[4, :]  # hdot = dh/dt row
    c[4, 0], c[4, 1] = u0 / v0, w0 / v0
    return ct.ss(a, b, c, np.zeros((5, 2)), inputs=["elev", "thr_in"], outputs=["theta", "q", "h", "hdot", "v"])


def _mimo_ss(rows: list[list], inputs: list[str], outputs: list[str]) -> ct.StateSpace:
    """State space of a matrix of SISO transfer functions (rows: outputs), one realisation per
    element stacked block-diagonally (python-control converts MIMO transfer functions only with
    slycot)."""
    blocks = [(j, i, ct.ss(e)) for j, r in enumerate(rows) for i, e in enumerate(r)]
    n = sum(b.nstates for _, _, b in blocks)
    a, b_, c, d = (
        np.zeros((n, n)),
        np.zeros((n, len(inputs))),
        np.zeros((len(outputs), n)),
        np.zeros((len(outputs), len(inputs))),
    )
    k = 0
    for j, i, blk in blocks:
        m = blk.nstates
        a[k : k + m, k : k + m] = blk.A
        b_[k : k + m, i] = blk.B[:, 0]
        c[j, k : k + m] = blk.C[0, :]
        d[j, i] += blk.D[0, 0]
        k += m
    return ct.ss(a, b_, c, d, inputs=inputs, outputs=outputs)


def _discrete_lowpass_pole(tc: float, dt: float = TECS_DT) -> float:
    """Continuous pole [rad/s] of the autopilot's discrete low-pass x += (u - x) dt / (tc + dt)."""
    return -math.log(1.0 - dt / (tc + dt)) / dt


def _tecs(g: HapsGains, v0: float, tas_per_eas: float) -> ct.InputOutputSystem:
    """TECS as an LTI system: inputs [h_ref, h_ref_rate, h, hdot, v]; outputs [pitch_out, thr_out]."""
    grav = STANDARD_GRAVITY
    wv = _discrete_lowpass_pole(g.tas_filter_s)
    wd = _discrete_lowpass_pole(g.vdot_filter_s)
    fv = wv / (S + wv)
    vd = S * fv * wd / (S + wd)
    ap = HapsAutopilot(g)
    dv = 1e-3
    dff_dv = (
        ap._level_throttle(v0 + dv, (v0 + dv) / tas_per_eas, 0.0)
        - ap._level_throttle(v0 - dv, (v0 - dv) / tas_per_eas, 0.0)
    ) / (2 * dv)
    k = g.mass_kg / (g.prop_efficiency * g.power_max_w)
    w = g.spd_weight
    one = ct.tf(1.0, 1.0)

    def lin(*terms) -> list:
        """Sum of coefficient x signal; a signal is its transfer function from each input
        [h_ref, h_ref_rate, h, hdot, v]."""
        return [sum((c * sig[i] for c, sig in terms), 0 * one) for i in range(5)]

    hdot_dem = [one / g.alt_time_const_s, one, -one / g.alt_time_const_s, 0 * one, 0 * one]
    vdot_dem = [0 * one] * 4 + [-fv * (1.0 / g.spd_time_const_s)]
    hdot_m = [0 * one] * 3 + [one, 0 * one]
    vdot_m = [0 * one] * 4 + [vd]
    herr = [one, 0 * one, -one, 0 * one, 0 * one]
    v_f = [0 * one] * 4 + [fv]
    ste_rate_dem = lin((grav, hdot_dem), (v0, vdot_dem))
    ste_rate_err = lin((1.0, ste_rate_dem), (-grav, hdot_m), (-v0, vdot_m))
    ste_err = lin((grav, herr), (-v0, v_f))
    thr = lin((k * dff_dv, v_f), (k, ste_rate_dem), (k * g.thr_damp, ste_rate_err), (k * g.thr_integ / S, ste_err))
    seb_rate_dem = lin(((2 - w) * grav, hdot_dem), (-w * v0, vdot_dem))
    seb_rate_err = lin((1.0, seb_rate_dem), (-(2 - w) * grav, hdot_m), (w * v0, vdot_m))
    seb_err = lin(((2 - w) * grav, herr), (w * v0, v_f))
    per = 1.0 / (grav * v0)
    pitch = lin((per, seb_rate_dem), (per * g.pitch_damp, seb_rate_err), (per * g.pitch_integ / S, seb_err))
    delay = pade_delay(TECS_DT / 2)

    def row(r) -> list:
        return [ct.minreal(e * delay, verbose=False) for e in r]

    return _mimo_ss([row(pitch), row(thr)], ["h_ref", "h_ref_rate", "h", "hdot", "v"], ["pitch_out", "thr_out"])


def _pitch_hold(g: HapsGains, ctx: HapsTrimContext) -> ct.InputOutputSystem:
    """elevator = -[ s (kp + ki/p) (theta_cmd - theta) - s kd q ], 120 Hz half-step delay."""
    d = pade_delay(HAPS_DT / 2)
    pi = ctx.sched * (g.kp_pitch + g.ki_pitch / S)
    return _mimo_ss([[-pi * d, pi * d, ctx.sched * g.kd_pitch * d]], ["theta_cmd", "theta", "q"], ["elev"])


def tecs_system(lm: LinearModel, lag: ThrustLag, g: HapsGains, ctx: HapsTrimContext, *, open_at: str | None):
    """The linear TECS loop. ``open_at`` None: closed loop [h_ref, h_ref_rate] -> h. ``"pitch"``
    or ``"thr"``: that channel broken (input ``x_in`` into the plant side, output ``x_out`` from
    the TECS side), the other closed: L = -(x_out / x_in)."""
    plant = _plant(lm, lag)
    tas_per_eas = ctx.tas_mps / ctx.eas_mps
    tecs = _tecs(g, math.hypot(lm.x0[lm.states.index("u")], lm.x0[lm.states.index("w")]), tas_per_eas)
    hold = _pitch_hold(g, ctx)
    links = [["elev", "pitch_hold.elev"]]
    inputs, outputs = ["tecs.h_ref", "tecs.h_ref_rate"], ["plant.h"]
    for channel, into in (("pitch", "pitch_hold.theta_cmd"), ("thr", "plant.thr_in")):
        if channel == open_at:
            inputs, outputs = [into], [f"tecs.{channel}_out"]
        else:
            links.append([into, f"tecs.{channel}_out"])
    plant.name, tecs.name, hold.name = "plant", "tecs", "pitch_hold"
    conns = [
        ["plant.elev", "pitch_hold.elev"],
        ["pitch_hold.theta", "plant.theta"],
        ["pitch_hold.q", "plant.q"],
        ["tecs.h", "plant.h"],
        ["tecs.hdot", "plant.hdot"],
        ["tecs.v", "plant.v"],
        *links[1:],
    ]
    return ct.interconnect([plant, tecs, hold], connections=conns, inplist=inputs, outlist=outputs, check_unused=False)


def tecs_loops(lm: LinearModel, lag: ThrustLag, g: HapsGains, ctx: HapsTrimContext):
    """(L_pitch, L_thr, T) with T: [h_ref, h_ref_rate] -> h."""
    l_pitch = ct.minreal(-ct.ss2tf(tecs_system(lm, lag, g, ctx, open_at="pitch")), verbose=False)
    l_thr = ct.minreal(-ct.ss2tf(tecs_system(lm, lag, g, ctx, open_at="thr")), verbose=False)
    return l_pitch, l_thr, tecs_system(lm, lag, g, ctx, open_at=None)
