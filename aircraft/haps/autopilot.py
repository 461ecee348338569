"""HAPS outer loops: TECS (altitude and airspeed) and the bank command, run at 10 Hz.

Inputs: the vehicle estimate (:class:`sim.core.state.VehicleState`: MSL altitude [m], NED velocity
[m/s], Euler angles [rad], true and equivalent airspeed [m/s]) and a
:class:`sim.core.setpoints.FixedWingSetpoint` (bank [rad], MSL altitude [m], true airspeed [m/s]).
Output: JSBSim property commands for the inner loops of ``systems/attitude_hold.xml``
(``ap/roll-cmd-rad``, ``ap/pitch-cmd-rad`` [rad]) and both throttles (``fcs/throttle-cmd-norm[i]``,
0..1). The first call after :meth:`HapsAutopilot.reset` also carries the inner-loop gains and
limits (``ap/*``) and ``ap/engage`` = 1.

TECS (total energy control, after ArduPilot ``AP_TECS``), per unit mass [J/kg]:
- total energy  STE = g h + V^2/2   -> throttle: feed-forward (level-flight power of the drag
  polar in a turn, plus the demanded energy rate) + P on the energy-rate error + I on the energy
  error;
- energy balance SEB = (2-w) g h - w V^2/2 -> pitch: demanded balance rate / (g V) + P on the
  balance-rate error + I on the balance error (the I term holds the trim angle of attack).
Airspeed schedule: while the altitude demand is more than ``schedule_band_m`` away, the speed
demand is the climb or descent EAS (converted to TAS at the current density ratio).
Sink limit: ``sink_rate_max``, but never more than the drag polar's glide sink at the descent EAS
(TAS x CD/CL in level 1-g flight at the current density): lower down the airframe cannot lose
height faster at that airspeed with the motors at idle, so a larger sink demand would be flown
by diving faster than the schedule (EAS 11 instead of 9 m/s below 3 km). Bank: the setpoint's, limited to
``roll_limit_rad`` and to the bank of a ``turn_radius_min_m`` turn at the current TAS (slower, the
turn's yaw rate overbanks the long wing beyond full aileron), then slewed. Demands are
shaped first: the altitude and airspeed references move toward the setpoint no
faster than the climb/sink and acceleration limits and stay within the linear range of the
P loops, so integrators do not wind up on large steps. Integrators are clamped and frozen while
their output saturates in the direction of the error (anti-windup). Below ``eas_underspeed``
the pitch loop controls airspeed only (underspeed protection).

Plain float math only: ``update`` runs 10 times per simulated second.
"""

from __future__ import annotations

import math

from aircraft.haps.gains import RHO0, HapsGains
from sim.core.constants import STANDARD_GRAVITY
from sim.core.setpoints import FixedWingSetpoint
from sim.core.state import VehicleState

__all__ = ["HapsAutopilot", "HapsGains"]  # HapsGains re-exported for aircraft.registry

_THROTTLES = ("fcs/throttle-cmd-norm[0]", "fcs/throttle-cmd-norm[1]")


def _clamp(x: float, lo: float, hi: float) -> float:
    return lo if x < lo else min(x, hi)


class HapsAutopilot:
    """TECS + bank-command outer loop of the HAPS (see the module docstring)."""

    def __init__(self, gains: HapsGains):
        self.gains = gains
        self.debug: dict[str, float] = {}
        # throttle per unit of specific power [1 / (W/kg)]
        self._thr_per_power = gains.mass_kg / (gains.prop_efficiency * gains.power_max_w)
        self._fcs = {**gains.fcs_properties(), "ap/engage": 1.0}
        self._send_fcs = True
        self._is_reset = False
        self._h_ref = self._v_ref = self._v_prev = self._v_filt = 0.0
        self._vdot = self._roll_cmd = self._i_thr = self._i_pitch = 0.0

    def reset(self, state: VehicleState, throttle: float | None = None) -> None:
        """Start from ``state`` without a bump: references at the current altitude and airspeed,
        pitch integrator at the current pitch minus flight-path angle (the trim alpha), throttle
        integrator so that the first throttle equals ``throttle`` if given (e.g. after a trim)."""
        g = self.gains
        v = max(state.tas_mps, 1.0)
        self._h_ref = state.alt_msl_m
        self._v_ref = self._v_prev = self._v_filt = v
        self._vdot = 0.0
        self._roll_cmd = state.roll
        gamma = math.asin(_clamp(-float(state.vel_ned[2]) / v, -1.0, 1.0))
        self._i_pitch = _clamp(state.pitch - gamma, g.pitch_min_rad, g.pitch_max_rad)
        self._i_thr = 0.0
        if throttle is not None:
            ff = self._level_throttle(v, state.eas_mps, state.roll)
            self._i_thr = _clamp(throttle - ff, -g.thr_integ_limit, g.thr_integ_limit)
        self._send_fcs = True
        self._is_reset = True

    def _level_throttle(self, tas: float, eas: float, roll: float) -> float:
        """Throttle for level flight at ``tas``/``eas`` [m/s] and bank ``roll`` [rad]: drag polar
        power D V / eta over the maximum power (load factor 1/cos(roll) in the induced drag)."""
        g = self.gains
        q_s = 0.5 * RHO0 * max(eas, 1.0) ** 2 * g.wing_area_m2  # dynamic pressure x area [N]
        cl = g.mass_kg * STANDARD_GRAVITY / (max(math.cos(roll), 0.5) * q_s)
        power = q_s * (g.cd0 + g.k_induced * cl * cl) * tas / g.prop_efficiency
        return power / g.power_max_w

    def _glide_sink(self, tas_per_eas: float) -> float:
        """Sink rate [m/s] of the drag polar's glide at the descent EAS: TAS x CD / CL (1 g)."""
        g = self.gains
        q_s = 0.5 * RHO0 * g.descent_eas**2 * g.wing_area_m2
        cl = g.mass_kg * STANDARD_GRAVITY / q_s
        return g.descent_eas * tas_per_eas * (g.cd0 + g.k_induced * cl * cl) / cl

    def _scheduled_tas(self, sp: FixedWingSetpoint, h: float, tas_per_eas: float) -> float:
        """Airspeed demand [m/s TAS]: the climb or descent EAS of the schedule while the altitude
        demand is beyond the band, else the setpoint's."""
        g = self.gains
        dh = sp.altitude_m - h
        if dh > g.schedule_band_m:
            return g.climb_eas * tas_per_eas
        if dh < -g.schedule_band_m:
            return g.descent_eas * tas_per_eas
        return sp.tas_mps

    def update(self, state: VehicleState, sp: FixedWingSetpoint, dt: float) -> dict[str, float]:
        """One outer-loop step of ``dt`` [s]: property commands for JSBSim (see module docstring).
        Resets from ``state`` first if :meth:`reset` was never called."""
        if not self._is_reset:
            self.reset(state)
        g = self.gains
        h = state.alt_msl_m
        hdot = -float(state.vel_ned[2])
        # measured airspeed low-passed: pitot noise through the clamps and the underspeed switch
        # below would bias the flown airspeed (+3.4 m/s at 21 km on the EKF without it)
        tas_per_eas = max(state.tas_mps, 1.0) / max(state.eas_mps, 1.0)
        self._v_filt += (max(state.tas_mps, 1.0) - self._v_filt) * dt / (g.tas_filter_s + dt)
        v = self._v_filt
        eas = v / tas_per_eas

        # airspeed rate, low-passed finite difference [m/s^2]
        self._vdot += ((v - self._v_prev) / dt - self._vdot) * dt / (g.vdot_filter_s + dt)
        self._v_prev = v
        vdot = self._vdot

        # demand shaping: rate-limited references, kept within the P loops' linear range
        v_dem = _clamp(self._scheduled_tas(sp, h, tas_per_eas), g.eas_min * tas_per_eas, g.eas_max * tas_per_eas)
        v_lead = g.accel_max * g.spd_time_const_s
        v_ref = _clamp(
            self._v_ref + _clamp(v_dem - self._v_ref, -g.accel_max * dt, g.accel_max * dt), v - v_lead, v + v_lead
        )
        v_ref_rate = (v_ref - self._v_ref) / dt
        sink_max = min(g.sink_rate_max, self._glide_sink(tas_per_eas))
        h_ref = _clamp(
            self._h_ref + _clamp(sp.altitude_m - self._h_ref, -sink_max * dt, g.climb_rate_max * dt),
            h - sink_max * g.alt_time_const_s,
            h + g.climb_rate_max * g.alt_time_const_s,
        )
        h_ref_rate = (h_ref - self._h_ref) / dt
        self._v_ref, self._h_ref = v_ref, h_ref
        hdot_dem = _clamp(h_ref_rate + (h_ref - h) / g.alt_time_const_s, -sink_max, g.climb_rate_max)
        vdot_dem = _clamp(v_ref_rate + (v_ref - v) / g.spd_time_const_s, -g.accel_max, g.accel_max)

        # total energy -> throttle
        ste_rate_dem = STANDARD_GRAVITY * hdot_dem + v * vdot_dem
        ste_rate_err = ste_rate_dem - (STANDARD_GRAVITY * hdot + v * vdot)
        ste_err = STANDARD_GRAVITY * (h_ref - h) + 0.5 * (v_ref * v_ref - v * v)
        k = self._thr_per_power
        thr_ff = self._level_throttle(v, eas, state.roll) + k * ste_rate_dem
        i_thr = _clamp(self._i_thr + k * g.thr_integ * ste_err * dt, -g.thr_integ_limit, g.thr_integ_limit)
        thr_raw = thr_ff + k * g.thr_damp * ste_rate_err + i_thr
        thr = _clamp(thr_raw, g.throttle_min, g.throttle_max)
        if thr == thr_raw or (thr_raw > thr) == (i_thr < self._i_thr):
            self._i_thr = i_thr

        # energy balance -> pitch (speed only when underspeed)
        underspeed = eas < g.eas_underspeed
        w = 2.0 if underspeed else g.spd_weight
        seb_rate_dem = (2.0 - w) * STANDARD_GRAVITY * hdot_dem - w * v * vdot_dem
        seb_rate_err = seb_rate_dem - ((2.0 - w) * STANDARD_GRAVITY * hdot - w * v * vdot)
        seb_err = (2.0 - w) * STANDARD_GRAVITY * (h_ref - h) - w * 0.5 * (v_ref * v_ref - v * v)
        per_seb_rate = 1.0 / (STANDARD_GRAVITY * v)  # pitch [rad] per unit energy-balance rate [W/kg]
        i_pitch = _clamp(self._i_pitch + g.pitch_integ * seb_err * per_seb_rate * dt, g.pitch_min_rad, g.pitch_max_rad)
        pitch_raw = i_pitch + (seb_rate_dem + g.pitch_damp * seb_rate_err) * per_seb_rate
        pitch = _clamp(pitch_raw, g.pitch_min_rad, g.pitch_max_rad)
        if pitch == pitch_raw or (pitch_raw > pitch) == (i_pitch < self._i_pitch):
            self._i_pitch = i_pitch

        # bank: limited (and to the minimum turn radius at this airspeed), slew-rate limited
        bank_max = min(g.roll_limit_rad, math.atan(v * v / (STANDARD_GRAVITY * g.turn_radius_min_m)))
        roll_dem = _clamp(sp.roll_rad, -bank_max, bank_max)
        step = g.roll_rate_limit_rad_s * dt
        self._roll_cmd = _clamp(roll_dem, self._roll_cmd - step, self._roll_cmd + step)

        self.debug = {
            "h_ref_m": h_ref,
            "v_dem_mps": v_dem,
            "v_ref_mps": v_ref,
            "hdot_dem_mps": hdot_dem,
            "sink_max_mps": sink_max,
            "vdot_dem_mps2": vdot_dem,
            "vdot_mps2": vdot,
            "ste_err_jkg": ste_err,
            "ste_rate_err_wkg": ste_rate_err,
            "seb_err_jkg": seb_err,
            "seb_rate_err_wkg": seb_rate_err,
            "thr_ff": thr_ff,
            "i_thr": self._i_thr,
            "i_pitch_rad": self._i_pitch,
            "underspeed": float(underspeed),
            "bank_max_rad": bank_max,
        }
        cmds = {"ap/roll-cmd-rad": self._roll_cmd, "ap/pitch-cmd-rad": pitch, _THROTTLES[0]: thr, _THROTTLES[1]: thr}
        if self._send_fcs:
            cmds.update(self._fcs)
            self._send_fcs = False
        return cmds
