"""GeoJSON of a plan, its margin polygons and the storms, for Foxglove's Map panel.

GeoJSON (RFC 7946) is WGS84 [lon, lat]: local-level NED / (north, east) [m] shapes are converted
through sim.geodesy with the scenario ``origin``. Feature properties: ``kind`` ("plan", "margin",
"storm"), ``t`` [s] (sim time the shape is valid at) and, for the plan, its status and the
due time of every vertex (``times``).
"""

from __future__ import annotations

import json

import numpy as np
import shapely
from shapely.geometry import mapping
from shapely.geometry.base import BaseGeometry

from sim.core.plan import Plan
from sim.core.threats import StormSnapshot
from sim.geodesy import GeoPoint, ned_to_geodetic


def _lonlat(ne: np.ndarray, origin: GeoPoint) -> np.ndarray:
    lat, lon, _ = ned_to_geodetic(np.column_stack([ne[:, :2], np.zeros(len(ne))]), origin)
    return np.column_stack([lon, lat])


def _to_wgs84(geom: BaseGeometry, origin: GeoPoint) -> BaseGeometry:
    return shapely.transform(geom, lambda xy: _lonlat(xy, origin))


def plan_geojson(
    plan: Plan, origin: GeoPoint, margins: BaseGeometry | None = None, storms: StormSnapshot | None = None
) -> str:
    """FeatureCollection (a JSON string) with the plan as a LineString, the margin region valid
    at the plan time and the storm cells of ``storms``."""
    feats = [
        {
            "type": "Feature",
            "geometry": {"type": "LineString", "coordinates": _lonlat(plan.positions, origin).tolist()},
            "properties": {
                "kind": "plan",
                "t": plan.t,
                "status": plan.status.value,
                "planner": plan.planner,
                "times": [float(x) for x in plan.times],
            },
        }
    ]
    if margins is not None and not margins.is_empty:
        for part in shapely.get_parts(margins):
            feats.append(
                {
                    "type": "Feature",
                    "geometry": mapping(_to_wgs84(part, origin)),
                    "properties": {"kind": "margin", "t": plan.t},
                }
            )
    if storms is not None:
        for cell in storms.cells:
            feats.append(
                {
                    "type": "Feature",
                    "geometry": mapping(_to_wgs84(cell, origin)),
                    "properties": {"kind": "storm", "t": storms.t},
                }
            )
    return json.dumps({"type": "FeatureCollection", "features": feats})
