"""PX4-style multirotor outer loops (Python, 50 Hz) over the JSBSim inner loops.

Cascade (PX4 ``PositionControl``)::

    position P -> velocity PID (D on the measured acceleration, anti-windup, acceleration
    saturation, speed limits) -> acceleration -> collective thrust + attitude (hover-thrust
    feed-forward, tilt limit, vertical priority) -> JSBSim properties

The JSBSim FCS (``systems/flight-control.xml``) closes attitude -> body rate -> mixer every
240 Hz step. Frames and units: NED [m, m/s, m/s^2], Euler 3-2-1 angles [rad], thrust as a
fraction of the static sea-level maximum collective thrust.

Setpoints (:class:`sim.core.setpoints.MultirotorSetpoint`): a NaN position component leaves that
axis to the velocity feed-forward alone (velocity control); a NaN velocity component means no
feed-forward; a NaN yaw holds the yaw setpoint.

Take-off and landing: a landed vehicle keeps its motors at idle (stopped after
``land.disarm_delay_s``) until the setpoint is more than ``takeoff.climb_margin`` above it (or,
with a NaN down position, asks to climb); it then arms and climbs with a ramped climb-rate
limit. To land, demand a descent (down position NaN and a positive down velocity, or a position
at or below the ground): once the land detector sees ground contact, the thrust is cut to idle.
"""

from __future__ import annotations

import math

from aircraft.quadrotor.gains import MultirotorGains
from aircraft.quadrotor.land_detector import LandDetector
from sim.core.constants import STANDARD_GRAVITY
from sim.core.setpoints import MultirotorSetpoint
from sim.core.state import VehicleState

_TWO_PI = 2.0 * math.pi


def _wrap(a: float) -> float:
    """Angle wrapped to [-pi, pi) [rad]."""
    return (a + math.pi) % _TWO_PI - math.pi


class MultirotorController:
    """Position/velocity controller producing the JSBSim inner-loop commands.

    ``update`` returns the property commands of ``systems/flight-control.xml``; the first
    command after ``reset`` also carries the inner-loop gains of ``gains``. ``debug`` holds the
    intermediate values of the last update (setpoints, demands, integrators, mode).
    """

    def __init__(self, gains: MultirotorGains | None = None):
        self.gains = gains if gains is not None else MultirotorGains.load()
        self.debug: dict[str, float] = {}
        self._land = LandDetector(self.gains.land, self.gains.limits.hover_thrust)
        self.landed = True
        self.armed = False
        self._pending_gains: dict[str, float] | None = self.gains.fcs_properties()
        self._int_n = self._int_e = self._int_d = 0.0
        self._acc_n = self._acc_e = self._acc_d = 0.0
        self._v_prev = (0.0, 0.0, 0.0)
        self._yaw_sp = 0.0
        self._t_landed = 0.0
        self._t_flight = 0.0

    # -- life cycle -------------------------------------------------------------------------
    def reset(self, state: VehicleState, *, landed: bool = False) -> None:
        """Start from ``state``: in flight (holding), or ``landed`` on the ground, disarmed."""
        self.landed = landed
        self.armed = not landed
        self._t_landed = math.inf if landed else 0.0
        self._t_flight = math.inf  # no take-off ramp for a vehicle that starts in the air
        self._pending_gains = self.gains.fcs_properties()
        self._restart(state)

    def _restart(self, state: VehicleState) -> None:
        """Clear integrators, filters and the land detector; yaw setpoint = current yaw."""
        self._int_n = self._int_e = self._int_d = 0.0
        self._acc_n = self._acc_e = self._acc_d = 0.0
        vn, ve, vd = state.vel_ned.tolist()
        self._v_prev = (vn, ve, vd)
        self._yaw_sp = float(state.euler[2])
        self._land.reset()

    # -- one step -----------------------------------------------------------------------------
    def update(self, state: VehicleState, sp: MultirotorSetpoint, dt: float) -> dict[str, float]:
        """Commands for the next ``dt`` seconds, from the state and the setpoint (NED, SI)."""
        if self.landed:
            if self._takeoff_demanded(state, sp):
                self.landed = False
                self.armed = True
                self._t_flight = 0.0
                self._restart(state)
            else:
                return self._ground(state, dt)
        return self._fly(state, sp, dt)

    def _takeoff_demanded(self, state: VehicleState, sp: MultirotorSetpoint) -> bool:
        spd = float(sp.pos_ned[2])
        if spd == spd:  # not NaN
            return float(state.pos_ned[2]) - spd > self.gains.takeoff.climb_margin
        return float(sp.vel_ned[2]) < 0.0

    def _ground(self, state: VehicleState, dt: float) -> dict[str, float]:
        """On the ground: thrust cut (motors at idle, no attitude torque), stopped after the disarm
        delay."""
        self._t_landed += dt
        if self._t_landed >= self.gains.land.disarm_delay_s:
            self.armed = False
        roll, pitch, yaw = state.euler.tolist()
        self._restart(state)
        self.debug.update(landed=1.0, armed=float(self.armed), thrust=0.0)
        return self._commands(0.0, roll, pitch, yaw, 0.0, landed=True)

    def _fly(self, state: VehicleState, sp: MultirotorSetpoint, dt: float) -> dict[str, float]:
        g = self.gains
        lim, pg, vg = g.limits, g.position, g.velocity
        pn, pe, pd = state.pos_ned.tolist()
        vn, ve, vd = state.vel_ned.tolist()
        spn, spe, spd = sp.pos_ned.tolist()
        ffn, ffe, ffd = (v if v == v else 0.0 for v in sp.vel_ned.tolist())  # NaN: no feed-forward

        # -- yaw setpoint: slew the shortest way to the demanded yaw --------------------------
        yaw_target = sp.yaw_rad if sp.yaw_rad == sp.yaw_rad else self._yaw_sp
        step_max = lim.max_yaw_rate_rad_s * dt
        yaw_step = min(max(_wrap(yaw_target - self._yaw_sp), -step_max), step_max)
        self._yaw_sp = _wrap(self._yaw_sp + yaw_step)

        # -- position P + feed-forward, speed limits --------------------------------------
        self._t_flight += dt
        ramp = min(1.0, self._t_flight / g.takeoff.ramp_s) if g.takeoff.ramp_s > 0.0 else 1.0
        vsn = ffn + (pg.kp_xy * (spn - pn) if spn == spn else 0.0)
        vse = ffe + (pg.kp_xy * (spe - pe) if spe == spe else 0.0)
        vsd = ffd + (pg.kp_z * (spd - pd) if spd == spd else 0.0)
        v_h = math.hypot(vsn, vse)
        if v_h > lim.max_speed_xy:
            k = lim.max_speed_xy / v_h
            vsn *= k
            vse *= k
        vsd = min(max(vsd, -lim.max_climb * ramp), lim.max_descent)

        # -- velocity PID (D on the low-passed measured acceleration) -------------------------
        alpha = dt / (dt + 1.0 / (_TWO_PI * vg.d_cutoff_hz))
        vn0, ve0, vd0 = self._v_prev
        self._acc_n += alpha * ((vn - vn0) / dt - self._acc_n)
        self._acc_e += alpha * ((ve - ve0) / dt - self._acc_e)
        self._acc_d += alpha * ((vd - vd0) / dt - self._acc_d)
        self._v_prev = (vn, ve, vd)
        en, ee, ed = vsn - vn, vse - ve, vsd - vd
        acn = vg.kp_xy * en + self._int_n - vg.kd_xy * self._acc_n
        ace = vg.kp_xy * ee + self._int_e - vg.kd_xy * self._acc_e
        acd = vg.kp_z * ed + self._int_d - vg.kd_z * self._acc_d
        a_h = math.hypot(acn, ace)
        if a_h > lim.max_accel_xy:
            k = lim.max_accel_xy / a_h
            asn, ase = acn * k, ace * k
        else:
            asn, ase = acn, ace

        # -- acceleration -> thrust vector (NED, fraction of max collective thrust) ---------
        bzn, bze, bzd = -asn, -ase, STANDARD_GRAVITY  # body z axis (down) before normalising
        nrm = math.sqrt(bzn * bzn + bze * bze + bzd * bzd)
        bzn, bze, bzd = bzn / nrm, bze / nrm, bzd / nrm
        cos_max = math.cos(lim.max_tilt_rad)
        if bzd < cos_max:  # tilt limit: rotate body z back towards the vertical
            k = math.sin(lim.max_tilt_rad) / math.hypot(bzn, bze)
            bzn, bze, bzd = bzn * k, bze * k, cos_max
        hover = lim.hover_thrust
        collective = min((acd * hover / STANDARD_GRAVITY - hover) / bzd, -lim.thrust_min)
        tn, te, td = bzn * collective, bze * collective, bzd * collective

        # vertical anti-windup: stop integrating into a saturated vertical thrust
        if (td >= -lim.thrust_min and ed >= 0.0) or (td <= -lim.thrust_max and ed <= 0.0):
            ed = 0.0
        # vertical priority, keeping a horizontal margin
        t_h = math.hypot(tn, te)
        t_max2 = lim.thrust_max * lim.thrust_max
        alloc_h = min(t_h, lim.thrust_xy_margin)
        td = max(td, -math.sqrt(t_max2 - alloc_h * alloc_h))
        rest = t_max2 - td * td
        t_h_max = math.sqrt(rest) if rest > 0.0 else 0.0
        if t_h > t_h_max:
            k = t_h_max / t_h
            tn, te = tn * k, te * k
        # horizontal tracking anti-windup against the acceleration actually produced
        apn, ape = tn * (STANDARD_GRAVITY / hover), te * (STANDARD_GRAVITY / hover)
        if acn * acn + ace * ace > apn * apn + ape * ape:
            arw = 2.0 / vg.kp_xy
            en -= arw * (acn - apn)
            ee -= arw * (ace - ape)
        self._int_n += vg.ki_xy * en * dt
        self._int_e += vg.ki_xy * ee * dt
        self._int_d += vg.ki_z * ed * dt

        # -- thrust vector + yaw -> attitude (body x perpendicular to the yaw's y axis) -------
        thrust = math.sqrt(tn * tn + te * te + td * td)
        bzn, bze, bzd = -tn / thrust, -te / thrust, -td / thrust
        cy, sy = math.cos(self._yaw_sp), math.sin(self._yaw_sp)
        bxn, bxe, bxd = cy * bzd, sy * bzd, -sy * bze - cy * bzn
        nrm = math.sqrt(bxn * bxn + bxe * bxe + bxd * bxd)
        bxn, bxe, bxd = bxn / nrm, bxe / nrm, bxd / nrm
        byd = bzn * bxe - bze * bxn
        roll = math.atan2(byd, bzd)
        pitch = math.asin(max(-1.0, min(1.0, -bxd)))

        # -- land detection -----------------------------------------------------------------
        v_h = math.hypot(vn, ve)
        if self._land.update(vsd > 0.0, vd, v_h, thrust, dt):
            self.landed = True
            self._t_landed = 0.0
            return self._ground(state, dt)

        d = self.debug
        d["landed"] = 0.0
        d["armed"] = 1.0
        d["vel_sp_n"], d["vel_sp_e"], d["vel_sp_d"] = vsn, vse, vsd
        d["acc_sp_n"], d["acc_sp_e"], d["acc_sp_d"] = acn, ace, acd
        d["int_n"], d["int_e"], d["int_d"] = self._int_n, self._int_e, self._int_d
        d["thrust"] = thrust
        d["tilt"] = math.acos(min(1.0, bzd))
        d["yaw_sp"] = self._yaw_sp
        return self._commands(thrust, roll, pitch, self._yaw_sp, yaw_step / dt, landed=False)

    def _commands(
        self, thrust: float, roll: float, pitch: float, yaw: float, yaw_rate: float, *, landed: bool
    ) -> dict[str, float]:
        cmd = {
            "ap/armed": 1.0 if self.armed else 0.0,
            "ap/landed": 1.0 if landed else 0.0,
            "ap/thrust-cmd-norm": thrust,
            "ap/roll-cmd-rad": roll,
            "ap/pitch-cmd-rad": pitch,
            "ap/yaw-cmd-rad": yaw,
            "ap/yaw-rate-ff-rps": yaw_rate,
        }
        if self._pending_gains is not None:
            cmd.update(self._pending_gains)
            self._pending_gains = None
        return cmd
