"""An airframe's contact hull as its JSBSim model declares it: the ``<contact>`` points of
``<ground_reactions>``, in the body frame FRD from the CG [m].

JSBSim's structural frame is x aft, y right, z up [m or in], so a point ``s`` lies at
``(-(s_x - cg_x), s_y - cg_y, -(s_z - cg_z))`` in FRD. ``BOGEY`` contacts are landing gear (made
to touch the ground); ``STRUCTURE`` contacts are the rest of the airframe (wing tips, motor
arms, top plate), which touch the ground only in a crash.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

_TO_M = {"M": 1.0, "IN": 0.0254, "FT": 0.3048}


class HullError(ValueError):
    """A JSBSim model without usable contact points."""


@dataclass(frozen=True, slots=True)
class Hull:
    """Contact points ``points_frd`` (K, 3) [m] from the CG, body FRD; ``gear`` (K,) true for
    landing gear; ``names`` as in the model."""

    points_frd: np.ndarray
    gear: np.ndarray
    names: tuple[str, ...]

    def heights(self, up_cg_m: np.ndarray | float, roll: np.ndarray | float, pitch: np.ndarray | float) -> np.ndarray:
        """Height of every point above the ground [m] for CG heights ``up_cg_m`` above it and
        attitudes ``roll``, ``pitch`` [rad] (yaw does not move points vertically); shape
        (..., K) for inputs of shape (...)."""
        up, r, p = (np.asarray(a, float)[..., None] for a in (up_cg_m, roll, pitch))
        x, y, z = self.points_frd.T
        down = -np.sin(p) * x + np.sin(r) * np.cos(p) * y + np.cos(r) * np.cos(p) * z  # row 3 of FRD->NED
        return up - down


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
    names, gear, pts = [], [], []
    for k, c in enumerate(contacts):
        name = c.get("name", f"contact[{k}]")
        s = _location_m(c.find("location"), f"{xml_path}: {name}") - cg
        pts.append((-s[0], s[1], -s[2]))
        gear.append(c.get("type", "BOGEY").upper() == "BOGEY")
        names.append(name)
    return Hull(np.array(pts, float), np.array(gear, bool), tuple(names))
