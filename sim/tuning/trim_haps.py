"""HAPS trim over an altitude x true-airspeed envelope: JSBSim's trim and the casadi trim.

For every grid point (altitude MSL [m], TAS [m/s], ISA, no wind, wings level, level flight):

- ``jsbsim``: JSBSim's full trim (``simulation/do_simple_trim`` = 1) on the real model; residual
  accelerations read back from JSBSim (translational [m/s^2], rotational [rad/s^2]).
- ``casadi``: the independent Newton trim of :class:`sim.tuning.surrogate.HapsTrimModel`; its
  own residual, and optionally (``check_in_jsbsim``) the accelerations JSBSim computes at the
  casadi solution (propellers settled at its throttle) — the cross-check that the surrogate is
  the same aircraft.

A point that does not trim is kept, with the reason (``ok`` False, ``reason``).
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
from sim.tuning.surrogate import HapsTrimModel

ORIGIN = GeoPoint(47.0, 8.0, 0.0)
HAPS_DT = 1.0 / 120.0
DEFAULT_ALTITUDES_M = (16_000.0, 17_000.0, 18_000.0, 19_000.0, 20_000.0, 21_000.0)
DEFAULT_TAS_MPS = (22.0, 25.0, 28.0, 31.0, 34.0, 37.0)
# Tolerances of a good trim: translational [m/s^2], rotational [rad/s^2]
TOL_ACC = 1e-3
TOL_ROT = 1e-4
# JSBSim's accelerations at the casadi trim: the flat, non-rotating earth of the surrogate leaves
# the Coriolis acceleration 2 Omega sin(lat) V (~3e-3 m/s^2 at 47 deg N, 30 m/s) unbalanced.
TOL_ACC_CROSS = 6e-3


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

    def row(self) -> dict:
        return asdict(self)


def haps_plant(alt_m: float, tas_mps: float) -> JSBSimPlant:
    """A HAPS plant initialised (not trimmed) at ``alt_m`` MSL, ``tas_mps`` TAS, heading north."""
    plant = JSBSimPlant("haps", HAPS_DT, ORIGIN, airframe_dir("haps"))
    plant.initialise(InitialConditions(GeoPoint(ORIGIN.lat_deg, ORIGIN.lon_deg, alt_m), tas_mps=tas_mps))
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
        if not (acc < TOL_ACC_CROSS and rot < TOL_ROT):
            pt.ok = False
            pt.reason = f"JSBSim disagrees at the casadi trim ({acc:.1e} m/s^2, {rot:.1e} rad/s^2)"
    return pt


def jsbsim_residual_at(
    alt_m: float, tas_mps: float, alpha: float, elevator_norm: float, throttle: float
) -> tuple[float, float]:
    """JSBSim's accelerations in level flight at ``alpha`` [rad] with the given elevator and
    throttle, propellers settled: (max translational [m/s^2], max rotational [rad/s^2])."""
    plant = haps_plant(alt_m, tas_mps)
    ev = JSBSimEvaluator(plant)
    x = np.array([tas_mps * math.cos(alpha), 0.0, tas_mps * math.sin(alpha), 0.0, 0.0, 0.0, 0.0, alpha, 0.0, alt_m])
    inputs = {
        "fcs/elevator-cmd-norm": elevator_norm,
        "fcs/pitch-trim-cmd-norm": 0.0,
        "fcs/throttle-cmd-norm[0]": throttle,
        "fcs/throttle-cmd-norm[1]": throttle,
    }
    ev.settle_engines(x, inputs, rtol=1e-9)
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
