"""casadi model of the HAPS longitudinal trim equations, built from the aircraft's own XML.

Why a surrogate read from the XML rather than JSBSim in the loop: casadi needs the equations as
expressions to differentiate them exactly (a JSBSim call would be a black box with finite
differences), and an independent implementation of the same tables checks JSBSim's trim
*and* our reading of the model — the two trims agreeing to ~0.01 deg says both are right.

What is read from ``haps.xml``, ``engine/haps_prop.xml`` and ``engine/haps_motor.xml``: the
CL(alpha) and CD-stall tables (linear interpolation, as JSBSim does), every ``<value>`` of the
lift, drag and pitch coefficient functions by name, wing area and chord, mass, elevator travel
(the ``fcs/elevator-pos-rad`` gain), propeller diameter and C_T(J), C_P(J) tables, motor power.

Equations (level flight, wings level, no wind, flight-path angle 0 so theta = alpha; body axes
x forward, z down; thrust along body x through the CG height, as in the XML)::

    X:  2 T + L sin(a) - D cos(a) - m g sin(a) = 0
    Z:  -L cos(a) - D sin(a) + m g cos(a)      = 0
    M:  Cm0 + Cm_a a + Cm_de de                = 0
    P:  C_P(J) rho n^3 D^5 - throttle P_max    = 0     (per motor; J = u / (n D), u = V cos a)

Unknowns: alpha [rad], elevator [normalised, +1 = full trailing-edge down], throttle [0..1],
propeller speed n [rev/s]. Density from the ISA (:mod:`sim.sensors.isa`); gravity
g0 (R/(R+h))^2, R = 6 371 km (JSBSim's own gravity model differs by < 0.1 % here).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

from aircraft import airframe_dir
from sim.core.constants import STANDARD_GRAVITY
from sim.sensors import isa

R_EARTH = 6_371_000.0
_M2_PER_FT2 = 0.3048**2


def _find(root: ET.Element, xpath: str) -> ET.Element:
    node = root.find(xpath)
    if node is None:
        raise ValueError(f"element {xpath!r} not found")
    return node


def _text(node: ET.Element) -> str:
    if node.text is None:
        raise ValueError(f"element <{node.tag}> has no text")
    return node.text


def _table(root: ET.Element, xpath: str) -> tuple[np.ndarray, np.ndarray]:
    rows = np.array([[float(v) for v in line.split()] for line in _text(_find(root, xpath)).strip().splitlines()])
    return rows[:, 0], rows[:, 1]


def _function_value(root: ET.Element, name: str) -> float:
    for fn in root.iter("function"):
        if fn.get("name") == name:
            return float(_text(_find(fn, ".//value")))
    raise ValueError(f"function {name!r} not found in haps.xml")


def _si(node: ET.Element, factors: dict[str, float]) -> float:
    return float(_text(node)) * factors.get(node.get("unit", ""), 1.0)


@dataclass(frozen=True)
class HapsAeroData:
    """Numbers of the HAPS model as read from its XML files (SI, radians)."""

    mass_kg: float
    wing_area_m2: float
    chord_m: float
    cl_alpha_deg: np.ndarray
    cl_table: np.ndarray
    cd_stall_alpha_deg: np.ndarray
    cd_stall_table: np.ndarray
    cl_de: float
    cd0: float
    k_induced: float
    cm0: float
    cm_alpha: float
    cm_de: float
    elevator_max_rad: float
    alpha_max_rad: float
    prop_diameter_m: float
    prop_j: np.ndarray
    prop_ct: np.ndarray
    prop_cp: np.ndarray
    motor_power_w: float
    n_motors: int

    @classmethod
    def from_xml(cls, folder: Path | None = None) -> HapsAeroData:
        d = Path(folder) if folder else airframe_dir("haps")
        ac = ET.parse(d / "haps.xml").getroot()
        prop = ET.parse(d / "engine" / "haps_prop.xml").getroot()
        motor = ET.parse(d / "engine" / "haps_motor.xml").getroot()
        length = {"M": 1.0, "FT": 0.3048}
        cla, clt = _table(ac, ".//function[@name='aero/haps/cl-static']/table/tableData")
        cda, cdt = _table(ac, ".//function[@name='aero/coefficient/CD_stall']//tableData")
        j, ct = _table(prop, ".//table[@name='C_THRUST']/tableData")
        j2, cp = _table(prop, ".//table[@name='C_POWER']/tableData")
        assert np.allclose(j, j2)
        elev = next(g for g in ac.iter("pure_gain") if g.get("name") == "fcs/elevator-pos-rad")
        area = _find(ac, "metrics/wingarea")
        return cls(
            mass_kg=_si(_find(ac, "mass_balance/emptywt"), {"KG": 1.0, "LBS": 0.45359237}),
            wing_area_m2=float(_text(area)) * (1.0 if area.get("unit") == "M2" else _M2_PER_FT2),
            chord_m=_si(_find(ac, "metrics/chord"), length),
            cl_alpha_deg=cla,
            cl_table=clt,
            cd_stall_alpha_deg=cda,
            cd_stall_table=cdt,
            cl_de=_function_value(ac, "aero/coefficient/CL_de"),
            cd0=_function_value(ac, "aero/coefficient/CD_0"),
            k_induced=_function_value(ac, "aero/coefficient/CD_i"),
            cm0=_function_value(ac, "aero/coefficient/Cm_0"),
            cm_alpha=_function_value(ac, "aero/coefficient/Cm_alpha"),
            cm_de=_function_value(ac, "aero/coefficient/Cm_de"),
            elevator_max_rad=float(_text(_find(elev, "gain"))),
            alpha_max_rad=math.radians(float(_text(_find(ac, "aerodynamics/alphalimits/max")))),
            prop_diameter_m=_si(_find(prop, "diameter"), length),
            prop_j=j,
            prop_ct=ct,
            prop_cp=cp,
            motor_power_w=_si(_find(motor, "power"), {"WATTS": 1.0, "HP": 745.69987}),
            n_motors=len(ac.findall("propulsion/engine")),
        )


def density(h_m: float) -> float:
    """ISA density [kg/m^3] at geometric altitude ``h_m`` [m]."""
    return isa.density_at_altitude(h_m)


def gravity(h_m: float) -> float:
    """Gravity [m/s^2] at altitude ``h_m`` (inverse square from g0 at sea level)."""
    return STANDARD_GRAVITY * (R_EARTH / (R_EARTH + h_m)) ** 2


class HapsTrimModel:
    """The residual function r(z; h, V) of the level-flight trim, z = [alpha, de, throttle, n]."""

    def __init__(self, data: HapsAeroData | None = None):
        self.data = d = data or HapsAeroData.from_xml()
        cl = ca.interpolant("cl", "linear", [np.radians(d.cl_alpha_deg)], d.cl_table)
        cds = ca.interpolant("cd_stall", "linear", [np.radians(d.cd_stall_alpha_deg)], d.cd_stall_table)
        ctj = ca.interpolant("ct", "linear", [d.prop_j], d.prop_ct)
        cpj = ca.interpolant("cp", "linear", [d.prop_j], d.prop_cp)
        z = ca.MX.sym("z", 4)
        par = ca.MX.sym("par", 3)  # rho [kg/m^3], V [m/s], g [m/s^2]
        alpha, de, thr, n = z[0], z[1], z[2], z[3]
        rho, v, g = par[0], par[1], par[2]
        de_rad = de * d.elevator_max_rad
        qs = 0.5 * rho * v**2 * d.wing_area_m2
        cl_static = cl(alpha)
        lift = qs * (cl_static + d.cl_de * de_rad)
        drag = qs * (d.cd0 + d.k_induced * cl_static**2 + cds(alpha))
        cm = d.cm0 + d.cm_alpha * alpha + d.cm_de * de_rad
        dia = d.prop_diameter_m
        j = v * ca.cos(alpha) / (n * dia)
        thrust = ctj(j) * rho * n**2 * dia**4
        power = cpj(j) * rho * n**3 * dia**5
        w = d.mass_kg * g
        res = ca.vertcat(
            (d.n_motors * thrust + lift * ca.sin(alpha) - drag * ca.cos(alpha) - w * ca.sin(alpha)) / w,
            (-lift * ca.cos(alpha) - drag * ca.sin(alpha) + w * ca.cos(alpha)) / w,
            cm,
            (power - thr * d.motor_power_w) / d.motor_power_w,
        )
        self.residual = ca.Function("trim_residual", [z, par], [res], ["z", "par"], ["r"])
        self.outputs = ca.Function("trim_outputs", [z, par], [ca.vertcat(j, thrust, lift / qs, drag / qs)])
        self.solver = ca.rootfinder(
            "haps_trim", "newton", self.residual, {"abstol": 1e-12, "max_iter": 50, "error_on_fail": False}
        )

    def solve(self, h_m: float, tas_mps: float) -> dict:
        """Trim at altitude ``h_m`` [m] MSL and true airspeed ``tas_mps`` [m/s].

        Returns alpha/theta [rad], elevator [norm], throttle, prop speed [rev/s], J, thrust per
        motor [N], CL, CD, the residual norm (force residuals per unit weight, Cm, power per P_max)
        and ``ok`` (converged, physical: throttle in [0, 1], alpha below the XML's alpha limit).
        """
        d = self.data
        rho, g = density(h_m), gravity(h_m)
        par = [rho, tas_mps, g]
        cl_need = d.mass_kg * g / (0.5 * rho * tas_mps**2 * d.wing_area_m2)
        rising = (d.cl_alpha_deg >= -10.0) & (d.cl_alpha_deg <= d.cl_alpha_deg[np.argmax(d.cl_table)])
        a0 = float(
            np.interp(min(cl_need, d.cl_table.max() - 0.02), d.cl_table[rising], np.radians(d.cl_alpha_deg[rising]))
        )  # pre-stall branch
        z0 = [a0, -0.08, 0.3, tas_mps / (1.05 * d.prop_diameter_m)]
        z = np.array(self.solver(z0, par)).ravel()
        stats = self.solver.stats()
        r = np.array(self.residual(z, par)).ravel()
        j, thrust, cl, cd = np.array(self.outputs(z, par)).ravel()
        reason = ""
        if cl_need > d.cl_table.max():
            reason = f"below the 1-g stall speed: CL {cl_need:.2f} needed > CLmax {d.cl_table.max():.2f}"
        elif not stats.get("success", False) or not np.all(np.isfinite(z)) or np.max(np.abs(r)) > 1e-8:
            reason = (
                f"Newton did not converge (residual {np.max(np.abs(r)):.1e}; CL {cl_need:.2f} "
                f"needed, CLmax {d.cl_table.max():.2f})"
            )
        elif z[0] > d.alpha_max_rad:
            reason = f"alpha {math.degrees(z[0]):.1f} deg beyond the model's alpha limit"
        elif not 0.0 <= z[2] <= 1.0:
            reason = f"throttle {z[2]:.2f} outside [0, 1]"
        elif abs(z[1]) > 1.0:
            reason = f"elevator {z[1]:.2f} beyond full travel"
        return {
            "alpha_rad": z[0],
            "theta_rad": z[0],
            "elevator_norm": z[1],
            "throttle": z[2],
            "prop_rps": z[3],
            "J": j,
            "thrust_n": thrust,
            "CL": cl,
            "CD": cd,
            "residual": float(np.max(np.abs(r))),
            "rho": rho,
            "ok": not reason,
            "reason": reason,
        }
