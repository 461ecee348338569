"""Multirotor trim in hover and level forward flight, by root-finding on JSBSim's accelerations.

JSBSim's own trim cannot trim rotorcraft (it assumes wing lift; JSBSim issue #1139), so the
trim is solved here: ``scipy.optimize.root`` (MINPACK hybrid Powell, finite-difference Jacobian)
on f(z) = JSBSim accelerations at the flight condition, z = [theta, phi, T, d_roll, d_pitch,
d_yaw] (pitch and roll [rad]; collective and differential ESC throttles). Motor throttles use the
mixer signs of ``aircraft/quadrotor/systems/flight-control.xml`` (engine order FR, AL, FL, AR)::

    FR = T - d_roll + d_pitch + d_yaw    AL = T + d_roll - d_pitch + d_yaw
    FL = T + d_roll + d_pitch - d_yaw    AR = T - d_roll - d_pitch - d_yaw

Flight condition: ground speed V [m/s] due north (no wind: airspeed = ground speed), level,
heading north, body rates zero. Residual: [u,v,w]_dot [m/s^2] and [p,q,r]_dot [rad/s^2].

FCS bypass (the inner loops must not fight the trim): with every attitude and rate gain at 0, the
collective command at 1 and the arming gate on, each motor's mixer output is exactly 1 and its
ESC input is ``ap/motor-health[i]`` x 1: the motor-health property then *is* the throttle of
motor i (checked against ``fcs/throttle-pos-norm[i]`` after every solve). Propeller speeds are
settled at each evaluation (:meth:`JSBSimEvaluator.settle_engines`).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import root

from aircraft import airframe_dir
from sim.core.constants import STANDARD_GRAVITY
from sim.geodesy import GeoPoint
from sim.jsbsim_plant import InitialConditions, JSBSimPlant
from sim.tuning.evaluator import JSBSimEvaluator
from sim.tuning.trim_haps import TrimPoint

ORIGIN = GeoPoint(47.0, 8.0, 0.0)
QUAD_DT = 1.0 / 240.0
DEFAULT_ALTITUDES_M = (100.0, 1000.0)
DEFAULT_SPEEDS_MPS = (0.0, 2.5, 5.0, 7.5, 10.0, 15.0, 20.0, 30.0)
MIX = np.array([[1, -1, 1, 1], [1, 1, -1, 1], [1, 1, 1, -1], [1, -1, -1, -1]], dtype=float)
TOL_ACC = 1e-4  # [m/s^2]
TOL_ROT = 1e-4  # [rad/s^2]
MAX_TILT_DEG = 35.0  # controller tilt limit (gains.toml [limits] max_tilt_deg)

ESC_SQRT_WEIGHT = 0.76  # ap/esc-sqrt-weight of systems/flight-control.xml


def bypass_properties() -> dict[str, float]:
    """Properties that turn the quadrotor FCS into a pass-through of ``ap/motor-health[i]``."""
    props = {
        "ap/armed": 1.0,
        "ap/landed": 1.0,
        "ap/thrust-cmd-norm": 1.0,
        "ap/kp-roll": 0.0,
        "ap/kp-pitch": 0.0,
        "ap/kp-yaw": 0.0,
        "ap/yaw-rate-ff-rps": 0.0,
    }
    for ax in ("roll", "pitch", "yaw"):
        for g in ("kp", "ki", "kd"):
            props[f"ap/{g}-{ax}-rate"] = 0.0
    return props


def hover_thrust_fraction(throttle: float) -> float:
    """Per-motor thrust fraction of a motor ``throttle``: inverse of the FCS's thrust
    linearisation throttle = w sqrt(f) + (1 - w) f (``ap/esc-sqrt-weight`` = ESC_SQRT_WEIGHT)."""
    w = ESC_SQRT_WEIGHT
    return ((-w + math.sqrt(w * w + 4 * (1 - w) * throttle)) / (2 * (1 - w))) ** 2


def quad_plant(alt_m: float) -> JSBSimPlant:
    plant = JSBSimPlant("quadrotor", QUAD_DT, ORIGIN, airframe_dir("quadrotor"))
    plant.initialise(InitialConditions(GeoPoint(ORIGIN.lat_deg, ORIGIN.lon_deg, alt_m)))
    return plant


def body_velocity(v_north: float, phi: float, theta: float) -> np.ndarray:
    """Body-axis velocity [m/s] of a vehicle moving north at ``v_north`` with heading north."""
    cp, sp, ct, st = math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta)
    # first column of the NED -> body DCM (psi = 0)
    return v_north * np.array([ct, sp * st, cp * st])


class QuadTrimProblem:
    """f(z) on a quadrotor plant at altitude ``alt_m`` and speed ``speed_mps``."""

    def __init__(self, alt_m: float, speed_mps: float, plant: JSBSimPlant | None = None):
        self.alt_m, self.speed = alt_m, speed_mps
        self.plant = plant or quad_plant(alt_m)
        self.ev = JSBSimEvaluator(self.plant)
        for k, v in bypass_properties().items():
            self.plant[k] = v
        self.evaluations = 0

    def state(self, z: np.ndarray) -> np.ndarray:
        theta, phi = z[0], z[1]
        uvw = body_velocity(self.speed, phi, theta)
        return np.array([*uvw, 0.0, 0.0, 0.0, phi, theta, 0.0, self.alt_m])

    def throttles(self, z: np.ndarray) -> np.ndarray:
        return MIX @ np.asarray(z[2:6])

    def residual(self, z: np.ndarray) -> np.ndarray:
        """[u,v,w]_dot / g and [p,q,r]_dot [rad/s^2] at z (engines settled)."""
        self.evaluations += 1
        x = self.state(z)
        u = self.throttles(z)
        self.ev.settle_engines(x, {f"ap/motor-health[{i}]": u[i] for i in range(4)}, rtol=1e-11)
        d = self.ev.derivatives(x)
        return np.concatenate([d[:3] / STANDARD_GRAVITY, d[3:6]])


def quad_trim(alt_m: float, speed_mps: float) -> TrimPoint:
    """Trim at one flight condition (see module docstring); failures carry their reason."""
    prob = QuadTrimProblem(alt_m, speed_mps)
    drag = 0.5 * 1.2 * speed_mps**2 * 0.0161
    z0 = np.array([-math.atan2(drag, 1.4 * 9.81), 0.0, 0.41, 0.0, 0.0, 0.0])
    try:
        sol = root(prob.residual, z0, method="hybr", options={"xtol": 1e-12, "eps": 1e-7})
        z = sol.x
        r = prob.residual(z)
    except RuntimeError as exc:  # engines never settled
        return TrimPoint("quadrotor", "scipy-root", alt_m, speed_mps, False, str(exc))
    f = prob.plant
    acc, rot = float(np.max(np.abs(r[:3]))) * STANDARD_GRAVITY, float(np.max(np.abs(r[3:])))
    u = prob.throttles(z)
    applied = [f[f"fcs/throttle-pos-norm[{i}]"] for i in range(4)]
    reason = ""
    if not np.allclose(applied, u, atol=1e-9):
        reason = f"FCS bypass failed: throttles {applied} instead of {u.tolist()}"
    elif not (acc < TOL_ACC and rot < TOL_ROT):
        reason = f"no root: {sol.message.strip()} (residual {acc:.1e} m/s^2, {rot:.1e} rad/s^2)"
    elif np.any(u < 0.0) or np.any(u > 1.0):
        reason = f"throttle outside [0, 1]: {np.round(u, 3).tolist()}"
    elif abs(math.degrees(z[0])) > MAX_TILT_DEG:
        reason = f"trimmable, but tilt {abs(math.degrees(z[0])):.1f} deg > the controller's {MAX_TILT_DEG} deg limit"
    x = prob.state(z)
    return TrimPoint(
        "quadrotor",
        "scipy-root",
        alt_m,
        speed_mps,
        not reason,
        reason,
        eas_mps=speed_mps * math.sqrt(f["atmosphere/rho-slugs_ft3"] / 0.00237689),
        alpha_deg=math.degrees(math.atan2(x[2], x[0])) if speed_mps > 0 else math.nan,
        pitch_deg=math.degrees(z[0]),
        roll_deg=math.degrees(z[1]),
        elevator_norm=math.nan,
        throttle=float(np.mean(u)),
        prop_rpm=f["propulsion/engine[0]/propeller-rpm"],
        residual_acc=acc,
        residual_rot=rot,
    )


def envelope(altitudes=DEFAULT_ALTITUDES_M, speeds=DEFAULT_SPEEDS_MPS, progress=None) -> list[TrimPoint]:
    rows = []
    for i, h in enumerate(altitudes):
        for k, v in enumerate(speeds):
            rows.append(quad_trim(h, v))
            if progress:
                progress(i * len(speeds) + k + 1, len(altitudes) * len(speeds))
    return rows
