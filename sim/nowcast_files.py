"""Storm nowcast files: one GeoJSON FeatureCollection, one Feature per storm cell and time step.

Format (documented in docs/mptp.md)::

    {"type": "FeatureCollection",
     "frame": "wgs84" | "local_ne",         # default "wgs84"
     "origin": {"lat_deg": 47.5, "lon_deg": 10.25},   # wgs84 only, unless given to the loader
     "features": [{"type": "Feature",
                   "geometry": {"type": "Polygon" | "MultiPolygon", "coordinates": ...},
                   "properties": {"t": 300.0,               # sim time of the step [s]
                                  "velocity_ne": [0.5, 9.8], # optional, cell motion [m/s]
                                  "base_m": 0.0,             # optional, altitude MSL [m]
                                  "top_m": 14000.0,          # optional, altitude MSL [m]
                                  "cell_id": "c7"}}]}        # optional, informative

"wgs84" coordinates are RFC 7946 [lon, lat] degrees, converted to the scenario's local-level NED
through sim.geodesy; "local_ne" coordinates are [north, east] metres from the scenario origin.
A MultiPolygon is several cells with the same properties. Within one time step either every
cell has a velocity or none has. A cell is the prism of its polygon between ``base_m`` (default:
from the ground) and ``top_m`` (default: no top), with top > base; the snapshots hold them as
heights above the origin's altitude (the scenario's origin, or the file's ``origin.alt_m``).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from shapely.geometry import Polygon, mapping, shape

from sim.core.threats import StormSnapshot
from sim.geodesy import GeoPoint, geodetic_to_ned, ned_to_geodetic

FRAMES = ("wgs84", "local_ne")


class NowcastError(ValueError):
    """A nowcast file that cannot be read; the message names the feature and field."""


def load_nowcast(path: str | Path, origin: GeoPoint | None = None) -> list[StormSnapshot]:
    """Snapshots in time order, shapes in (north, east) [m]."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise NowcastError(f"{path}: not readable as JSON ({e})") from e
    return parse_nowcast(doc, origin, str(path))


def load_series(paths: list[str] | list[Path], origin: GeoPoint | None = None) -> list[list[StormSnapshot]]:
    """A series of nowcast files, one per issue, in the given order: issue times (first steps)
    must increase and no file may be empty."""
    series = [load_nowcast(p, origin) for p in paths]
    for p, nc in zip(paths, series, strict=True):
        if not nc:
            raise NowcastError(f"{p}: no features")
    issued = [nc[0].t for nc in series]
    bad = [i for i in range(1, len(issued)) if issued[i] <= issued[i - 1]]
    if bad:
        raise NowcastError(f"{paths[bad[0]]}: issued at t={issued[bad[0]]} s, not after the previous file")
    return series


def parse_nowcast(doc: dict[str, Any], origin: GeoPoint | None = None, where: str = "nowcast") -> list[StormSnapshot]:
    if not isinstance(doc, dict) or doc.get("type") != "FeatureCollection":
        raise NowcastError(f"{where}: type: expected 'FeatureCollection'")
    frame = doc.get("frame", "wgs84")
    if frame not in FRAMES:
        raise NowcastError(f"{where}: frame: {frame!r} is not one of {FRAMES}")
    if frame == "wgs84" and origin is None:
        o: Any = doc.get("origin")  # JSON: checked by the conversions below
        try:
            origin = GeoPoint(float(o["lat_deg"]), float(o["lon_deg"]), float(o.get("alt_m", 0.0)))
        except (TypeError, KeyError, ValueError) as e:
            raise NowcastError(f"{where}: origin: wgs84 coordinates need an origin {{lat_deg, lon_deg}} ({e!r})") from e
    feats = doc.get("features")
    if not isinstance(feats, list):
        raise NowcastError(f"{where}: features: expected a list")
    alt0 = 0.0 if origin is None else origin.alt_m
    steps: dict[float, list[tuple[Polygon, np.ndarray | None, tuple[float, float]]]] = {}
    for i, f in enumerate(feats):
        at = f"{where}: features[{i}]"
        props = f.get("properties") if isinstance(f, dict) else None
        if not isinstance(props, dict):
            raise NowcastError(f"{at}.properties: expected an object")
        t = _number(props.get("t"), f"{at}.properties.t")
        vel = props.get("velocity_ne")
        if vel is not None:
            if not (isinstance(vel, list) and len(vel) == 2):
                raise NowcastError(f"{at}.properties.velocity_ne: expected [north, east] in m/s")
            vel = np.array([_number(v, f"{at}.properties.velocity_ne") for v in vel])
        ext = _extent(props, alt0, f"{at}.properties")
        for poly in _cells(f.get("geometry"), f"{at}.geometry", origin if frame == "wgs84" else None):
            steps.setdefault(t, []).append((poly, vel, ext))
    out = []
    for t in sorted(steps):
        cells = steps[t]
        has = [v is not None for _, v, _ in cells]
        if any(has) and not all(has):
            raise NowcastError(f"{where}: t={t}: some cells have properties.velocity_ne and some do not")
        vel = np.array([v for _, v, _ in cells]) if all(has) else None
        extents = np.array([e for _, _, e in cells])
        bounded = bool(np.isfinite(extents).any())
        out.append(StormSnapshot(t, tuple(p for p, _, _ in cells), vel, extents if bounded else None))
    return out


def _extent(props: dict[str, Any], alt0: float, at: str) -> tuple[float, float]:
    """[base, top] heights above the origin [m] from ``base_m``/``top_m`` (altitudes MSL [m])."""
    base, top = (
        sign * math.inf if props.get(k) is None else _number(props[k], f"{at}.{k}") - alt0
        for k, sign in (("base_m", -1.0), ("top_m", 1.0))
    )
    if not top > base:
        raise NowcastError(f"{at}.top_m: {top + alt0:g} m must be above base_m {base + alt0:g} m")
    return base, top


def _number(x: object, at: str) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
        raise NowcastError(f"{at}: expected a finite number, got {x!r}")
    return float(x)


def _cells(geom: object, at: str, origin: GeoPoint | None) -> list[Polygon]:
    """The polygons of a GeoJSON geometry in (north, east) [m]: coordinates (lon, lat) [deg] about
    ``origin``, or already local (north, east) [m] without one."""
    if not isinstance(geom, dict) or geom.get("type") not in ("Polygon", "MultiPolygon"):
        raise NowcastError(f"{at}.type: expected 'Polygon' or 'MultiPolygon'")
    try:
        g = shape(geom)
    except Exception as e:  # shapely raises several types for malformed coordinates
        raise NowcastError(f"{at}.coordinates: malformed ({e})") from e
    out = []
    for k, part in enumerate(shapely.get_parts(g)):
        xy = np.asarray(part.exterior.coords)
        if not np.isfinite(xy).all() or len(xy) < 4:
            raise NowcastError(f"{at}.coordinates[{k}]: need at least 3 finite points")
        ne = xy if origin is None else geodetic_to_ned(xy[:, 1], xy[:, 0], 0.0, origin)[:, :2]
        poly = Polygon(ne)
        if not poly.is_valid or poly.area <= 0:
            raise NowcastError(f"{at}.coordinates[{k}]: not a valid polygon ({shapely.is_valid_reason(poly)})")
        out.append(poly)
    return out


def dump_nowcast(
    snapshots: list[StormSnapshot], frame: str = "local_ne", origin: GeoPoint | None = None
) -> dict[str, Any]:
    """The GeoJSON document of ``snapshots`` (inverse of :func:`parse_nowcast`)."""
    if frame not in FRAMES or (frame == "wgs84" and origin is None):
        raise ValueError("frame must be 'local_ne', or 'wgs84' with an origin")
    geo = origin if frame == "wgs84" else None
    feats = []
    alt0 = 0.0 if origin is None else origin.alt_m
    for s in snapshots:
        ext = s.extents()
        for i, c in enumerate(s.cells):
            ne = np.asarray(c.exterior.coords)
            if geo is not None:
                lat, lon, _ = ned_to_geodetic(np.column_stack([ne, np.zeros(len(ne))]), geo)
                ne = np.column_stack([lon, lat])
            props: dict[str, Any] = {"t": float(s.t)}
            if s.velocities_ne is not None:
                props["velocity_ne"] = [float(v) for v in s.velocities_ne[i]]
            props.update(
                {k: float(h + alt0) for k, h in zip(("base_m", "top_m"), ext[i], strict=True) if math.isfinite(h)}
            )
            feats.append({"type": "Feature", "geometry": mapping(Polygon(ne)), "properties": props})
    doc: dict[str, Any] = {"type": "FeatureCollection", "frame": frame, "features": feats}
    if geo is not None:
        doc["origin"] = {"lat_deg": geo.lat_deg, "lon_deg": geo.lon_deg, "alt_m": geo.alt_m}
    return json.loads(json.dumps(doc))


def save_nowcast(
    path: str | Path, snapshots: list[StormSnapshot], frame: str = "local_ne", origin: GeoPoint | None = None
) -> None:
    Path(path).write_text(json.dumps(dump_nowcast(snapshots, frame, origin)))
