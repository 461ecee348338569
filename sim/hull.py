"""An airframe's contact hull as its JSBSim model declares it: the ``<contact>`` points of
``<ground_reactions>``, in the body frame FRD from the CG [m].

JSBSim's structural frame is x aft, y right, z up [m or in], so a point ``s`` lies at
``(-(s_x - cg_x), s_y - cg_y, -(s_z - cg_z))`` in FRD. ``BOGEY`` contacts are landing gear (made
to touch the ground); ``STRUCTURE`` contacts are the rest of the airframe (wing tips, motor
arms, top plate), which touch the ground only in a crash.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

_TO_M = {"M": 1.0, "IN": 0.0254, "FT": 0.3048}


class HullError(ValueError):
    """A JSBSim model without usable contact points."""


@dataclass(frozen=True, slots=True)
class Hull:
    """Contact points ``points`` (x, y, z) [m] from the CG, body FRD; ``gear`` true for landing
    gear; ``names`` as in the model. Plain tuples: it is evaluated after every plant step."""

    points: tuple[tuple[float, float, float], ...]
    gear: tuple[bool, ...]
    names: tuple[str, ...]

    @property
    def reach_m(self) -> float:
        """The farthest point's distance from the CG [m]."""
        return max(math.hypot(*p) for p in self.points)

    def heights(self, up_cg_m: float, roll: float, pitch: float) -> list[float]:
        """Height of every point above the ground [m] for a CG ``up_cg_m`` above it and attitude
        ``roll``, ``pitch`` [rad] (yaw does not move points vertically)."""
        sr, cr, sp, cp = math.sin(roll), math.cos(roll), math.sin(pitch), math.cos(pitch)
        a, b, c = -sp, sr * cp, cr * cp  # row 3 of FRD->NED
        return [up_cg_m - (a * x + b * y + c * z) for x, y, z in self.points]

    def touching(self, up_cg_m: float, roll: float, pitch: float) -> tuple[bool, bool]:
        """(any point touches the ground, a point that is not gear touches)."""
        h = self.heights(up_cg_m, roll, pitch)
        return any(v <= 0.0 for v in h), any(v <= 0.0 for v, g in zip(h, self.gear, strict=True) if not g)


def _location_m(elem: ET.Element | None, what: str) -> np.ndarray:
    if elem is None:
        raise HullError(f"{what}: no <location>")
    scale = _TO_M.get(elem.get("unit", "IN").upper())
    if scale is None:
        raise HullError(f"{what}: unknown unit {elem.get('unit')!r}")
    return np.array([float((elem.findtext(a) or "0").strip()) for a in ("x", "y", "z")]) * scale


def load_hull(xml_path: Path) -> Hull:
    """The contact hull of the JSBSim model file ``xml_path``."""
    root = ET.parse(xml_path).getroot()
    cg = _location_m(root.find("mass_balance/location[@name='CG']"), f"{xml_path}: CG")
    contacts = root.findall("ground_reactions/contact")
    if not contacts:
        raise HullError(f"{xml_path}: no <ground_reactions> contacts")
    names: list[str] = []
    gear: list[bool] = []
    pts: list[tuple[float, float, float]] = []
    for k, c in enumerate(contacts):
        name = c.get("name", f"contact[{k}]")
        s = _location_m(c.find("location"), f"{xml_path}: {name}") - cg
        pts.append((-float(s[0]), float(s[1]), -float(s[2])))
        gear.append(c.get("type", "BOGEY").upper() == "BOGEY")
        names.append(name)
    return Hull(tuple(pts), tuple(gear), tuple(names))
