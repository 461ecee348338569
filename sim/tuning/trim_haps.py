"""HAPS trim over an altitude x true-airspeed envelope: JSBSim's trim and the casadi trim.

For every grid point (altitude MSL [m], TAS [m/s], ISA, no wind, wings level, level flight):

- ``jsbsim``: JSBSim's full trim (``simulation/do_simple_trim`` = 1) on the real model; residual
  accelerations read back from JSBSim (translational [m/s^2], rotational [rad/s^2]).
- ``casadi``: the independent Newton trim of :class:`sim.tuning.surrogate.HapsTrimModel`; its
  own residual, and optionally (``check_in_jsbsim``) the accelerations JSBSim computes at the
  casadi solution (propellers settled at its throttle) — the cross-check that the surrogate is
  the same aircraft.

A point that does not trim is kept, with the reason (``ok`` False, ``reason``).

Why JSBSim's trim fails at low true airspeed (``udot doesn't appear to be trimmable``): before
every trim iteration ``FGPropulsion::GetSteadyState`` marches the propeller speed to steady state
with explicit Euler steps of a fixed 0.5 s (``in.TotalDeltaT = 0.5``, at most 6000 steps, steady
when the thrust changes by < 1e-4 lbf for 120 steps). Euler is stable only while the propeller's
speed time constant tau exceeds 0.25 s, and tau grows with inertia x airspeed (at constant EAS
n ~ TAS and shaft power ~ TAS, so tau ~ I n^2 / P ~ I TAS). With the model's 0.5 kg m^2 the pre-pass
diverges below TAS ~ 17 m/s (below ~12 km at EAS 8 m/s); the thrust never settles and no throttle
brackets udot = 0. Measured: 0.07 kg m^2 fails everywhere, 0.5 fails at 1-10 km and trims from
15 km up, 2.0 trims from 1 km up (``tests/test_haps_envelope.py``). The fix is in the trim
procedure, not the model: :func:`level_trim` puts the casadi trim (no time marching) into the
plant and settles the propellers by stepping JSBSim at its own dt, which is stable for any tau.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from aircraft import airframe_dir
from sim.core.constants import FT
from sim.geodesy import GeoPoint
from sim.jsbsim_plant import InitialConditions, JSBSimPlant, PlantError
from sim.tuning.evaluator import JSBSimEvaluator
from sim.tuning.surrogate import HapsTrimModel, density, gravity

RHO0 = 1.225  # ISA sea-level density [kg/m^3]: EAS = TAS sqrt(rho / RHO0)

ORIGIN = GeoPoint(47.0, 8.0, 0.0)
# Free-air trims: the flat ground lies this far below sea level so the skids touch nothing at 0 m.
FREE_AIR_TERRAIN_M = -1000.0
HAPS_DT = 1.0 / 120.0
DEFAULT_ALTITUDES_M = (16_000.0, 17_000.0, 18_000.0, 19_000.0, 20_000.0, 21_000.0)
DEFAULT_TAS_MPS = (22.0, 25.0, 28.0, 31.0, 34.0, 37.0)
DEFAULT_PROFILE_ALTITUDES_M = tuple(1000.0 * k for k in range(24))  # 0-23 km
# Tolerances of a good trim: translational [m/s^2], rotational [rad/s^2]
TOL_ACC = 1e-3
TOL_ROT = 1e-4
# JSBSim's accelerations at the casadi trim: the flat, non-rotating earth of the surrogate leaves
# the Coriolis acceleration 2 Omega sin(lat) V (~3e-3 m/s^2 at 47 deg N, 30 m/s) unbalanced.
TOL_ACC_CROSS = 6e-3
# ... and a rotational remainder that grows as TAS falls (1.0e-4 rad/s^2 at 0 m, EAS 8 m/s: a
# moment of 0.01 N m, Delta Cm ~ 2e-5), not traced to its source.
TOL_ROT_CROSS = 3e-4


@dataclass
class TrimPoint:
    """One trim result. Angles in degrees here (a table for people), SI otherwise."""

    airframe: str
    method: str
    alt_m: float
    tas_mps: float
    ok: bool
    reason: str = ""
    eas_mps: float = math.nan
    alpha_deg: float = math.nan
    pitch_deg: float = math.nan
    roll_deg: float = math.nan
    elevator_norm: float = math.nan
    throttle: float = math.nan
    prop_rpm: float = math.nan
    residual_acc: float = math.nan  # max |u_dot, v_dot, w_dot| [m/s^2]
    residual_rot: float = math.nan  # max |p_dot, q_dot, r_dot| [rad/s^2]
    residual_model: float = math.nan  # casadi: max |normalised residual| of its own equations
    shaft_power_w: float = math.nan  # all motors
    stall_margin: float = math.nan  # EAS / 1-g stall EAS (CLmax of the CL table)

    def row(self) -> dict:
        return asdict(self)


def haps_plant(alt_m: float, tas_mps: float) -> JSBSimPlant:
    """A HAPS plant initialised (not trimmed) at ``alt_m`` MSL, ``tas_mps`` TAS, heading north."""
    plant = JSBSimPlant("haps", HAPS_DT, ORIGIN, airframe_dir("haps"))
    plant.initialise(
        InitialConditions(
            GeoPoint(ORIGIN.lat_deg, ORIGIN.lon_deg, alt_m), tas_mps=tas_mps, terrain_alt_m=FREE_AIR_TERRAIN_M
        )
    )
    return plant


def _residuals(plant: JSBSimPlant) -> tuple[float, float]:
    acc = max(abs(plant[f"accelerations/{a}dot-ft_sec2"]) for a in "uvw") * FT
    rot = max(abs(plant[f"accelerations/{a}dot-rad_sec2"]) for a in "pqr")
    return acc, rot


def jsbsim_trim(alt_m: float, tas_mps: float) -> tuple[TrimPoint, JSBSimPlant | None]:
    """JSBSim's full trim at one point; the trimmed plant (None if the trim failed)."""
    plant = haps_plant(alt_m, tas_mps)
    try:
        plant.trim()
    except PlantError as exc:
        return TrimPoint("haps", "jsbsim", alt_m, tas_mps, False, str(exc).split(": ", 1)[-1]), None
    acc, rot = _residuals(plant)
    s = plant.truth()
    ok = acc < TOL_ACC and rot < TOL_ROT
    pt = TrimPoint(
        "haps",
        "jsbsim",
        alt_m,
        tas_mps,
        ok,
        "" if ok else f"residual above tolerance ({acc:.1e} m/s^2, {rot:.1e} rad/s^2)",
        eas_mps=s.eas_mps,
        alpha_deg=math.degrees(s.alpha_rad),
        pitch_deg=math.degrees(s.pitch),
        roll_deg=math.degrees(s.roll),
        elevator_norm=plant["fcs/elevator-pos-norm"],
        throttle=plant["fcs/throttle-cmd-norm[0]"],
        prop_rpm=plant["propulsion/engine[0]/propeller-rpm"],
        residual_acc=acc,
        residual_rot=rot,
    )
    return pt, plant


def casadi_trim(
    alt_m: float, tas_mps: float, model: HapsTrimModel | None = None, check_in_jsbsim: bool = False
) -> TrimPoint:
    """The casadi trim at one point; with ``check_in_jsbsim`` also JSBSim's accelerations there."""
    model = model or HapsTrimModel()
    s = model.solve(alt_m, tas_mps)
    pt = TrimPoint(
        "haps",
        "casadi",
        alt_m,
        tas_mps,
        s["ok"],
        s["reason"],
        eas_mps=tas_mps * math.sqrt(s["rho"] / 1.225),
        alpha_deg=math.degrees(s["alpha_rad"]),
        pitch_deg=math.degrees(s["theta_rad"]),
        roll_deg=0.0,
        elevator_norm=s["elevator_norm"],
        throttle=s["throttle"],
        prop_rpm=s["prop_rps"] * 60.0,
        residual_model=s["residual"],
    )
    if check_in_jsbsim and s["ok"]:
        acc, rot = jsbsim_residual_at(alt_m, tas_mps, s["alpha_rad"], s["elevator_norm"], s["throttle"])
        pt.residual_acc, pt.residual_rot = acc, rot
        if not (acc < TOL_ACC_CROSS and rot < TOL_ROT_CROSS):
            pt.ok = False
            pt.reason = f"JSBSim disagrees at the casadi trim ({acc:.1e} m/s^2, {rot:.1e} rad/s^2)"
    return pt


def _trim_inputs(elevator_norm: float, throttle: float) -> dict[str, float]:
    """Surface and throttle properties of a wings-level trim (elevator as the trim command, as
    JSBSim's trim; lateral commands and trims zeroed, also those a failed JSBSim trim left)."""
    return {
        "fcs/aileron-cmd-norm": 0.0,
        "fcs/rudder-cmd-norm": 0.0,
        "fcs/roll-trim-cmd-norm": 0.0,
        "fcs/yaw-trim-cmd-norm": 0.0,
        "fcs/elevator-cmd-norm": 0.0,
        "fcs/pitch-trim-cmd-norm": elevator_norm,
        "fcs/throttle-cmd-norm[0]": throttle,
        "fcs/throttle-cmd-norm[1]": throttle,
    }


def _level_state(alt_m: float, tas_mps: float, alpha: float, heading: float = 0.0) -> np.ndarray:
    return np.array(
        [tas_mps * math.cos(alpha), 0.0, tas_mps * math.sin(alpha), 0.0, 0.0, 0.0, 0.0, alpha, heading, alt_m]
    )


def level_trim(plant: JSBSimPlant, model: HapsTrimModel | None = None) -> dict:
    """Trim ``plant`` (initialised, engines running) for wings-level flight at its current
    altitude, true airspeed and heading with the casadi trim, propellers settled by stepping
    JSBSim (see the module docstring for why JSBSim's own trim cannot below ~12 km).

    Leaves the plant at the trim state, at its sim time from before, with the elevator in
    ``fcs/pitch-trim-cmd-norm`` and both throttles set, like JSBSim's trim. Returns the casadi
    solution; raises PlantError with the reason if the point does not trim (below the stall
    speed, throttle beyond 1).
    """
    tas = plant["velocities/vt-fps"] * FT
    alt = plant["position/h-sl-ft"] * FT
    heading = plant["attitude/psi-rad"]
    s = (model or HapsTrimModel()).solve(alt, tas)
    if not s["ok"]:
        raise PlantError(f"{plant.model}: level trim at {alt:.0f} m, TAS {tas:.1f} m/s failed: {s['reason']}")
    ev = JSBSimEvaluator(plant)
    x = _level_state(alt, tas, s["alpha_rad"], heading)
    t0 = plant.fdm.get_sim_time()
    ev.settle_engines(x, _trim_inputs(s["elevator_norm"], s["throttle"]), rtol=1e-9)
    plant.fdm.set_sim_time(t0)  # settling steps JSBSim: its clock must not run ahead of the scenario's
    ev.set_state(x)
    return s


def jsbsim_residual_at(
    alt_m: float, tas_mps: float, alpha: float, elevator_norm: float, throttle: float
) -> tuple[float, float]:
    """JSBSim's accelerations in level flight at ``alpha`` [rad] with the given elevator and
    throttle, propellers settled: (max translational [m/s^2], max rotational [rad/s^2])."""
    plant = haps_plant(alt_m, tas_mps)
    ev = JSBSimEvaluator(plant)
    x = _level_state(alt_m, tas_mps, alpha)
    ev.settle_engines(x, _trim_inputs(elevator_norm, throttle), rtol=1e-9)
    ev.set_state(x)
    return _residuals(plant)


def envelope(
    altitudes=DEFAULT_ALTITUDES_M, speeds=DEFAULT_TAS_MPS, check_in_jsbsim: bool = True, progress=None
) -> list[TrimPoint]:
    """Both trims over the grid; rows ordered altitude, speed, method (jsbsim then casadi)."""
    model = HapsTrimModel()
    rows: list[TrimPoint] = []
    total = len(altitudes) * len(speeds)
    for i, h in enumerate(altitudes):
        for k, v in enumerate(speeds):
            rows.append(jsbsim_trim(h, v)[0])
            rows.append(casadi_trim(h, v, model, check_in_jsbsim))
            if progress:
                progress(i * len(speeds) + k + 1, total)
    return rows


def tas_for_eas(alt_m: float, eas_mps: float) -> float:
    """True airspeed [m/s] of equivalent airspeed ``eas_mps`` at ``alt_m`` MSL (ISA)."""
    return eas_mps * math.sqrt(RHO0 / density(alt_m))


def stall_eas(model: HapsTrimModel, alt_m: float = 0.0) -> float:
    """1-g stall EAS [m/s]: CLmax of the model's CL table, gravity at ``alt_m``."""
    d = model.data
    return math.sqrt(2.0 * d.mass_kg * gravity(alt_m) / (RHO0 * d.wing_area_m2 * float(d.cl_table.max())))


def altitude_profile(
    altitudes=DEFAULT_PROFILE_ALTITUDES_M, eas_mps: float = 8.0, check_in_jsbsim: bool = True, progress=None
) -> list[TrimPoint]:
    """Both trims at one EAS over ``altitudes`` [m]: rows jsbsim then casadi per altitude, each
    with shaft power [W] and stall margin (EAS / 1-g stall EAS)."""
    model = HapsTrimModel()
    rows: list[TrimPoint] = []
    for i, h in enumerate(altitudes):
        tas = tas_for_eas(h, eas_mps)
        margin = eas_mps / stall_eas(model, h)
        for pt in (jsbsim_trim(h, tas)[0], casadi_trim(h, tas, model, check_in_jsbsim)):
            pt.stall_margin = margin
            pt.shaft_power_w = pt.throttle * model.data.motor_power_w * model.data.n_motors
            rows.append(pt)
        if progress:
            progress(i + 1, len(altitudes))
    return rows
