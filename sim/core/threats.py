"""Threats as a vehicle senses them, handed to planners (never the world's truth).

Frames and units: local-level NED from the scenario origin [m, m/s], times in sim seconds [s].
Vertical extents are heights above the origin's altitude, ``up = -D`` [m]. Horizontal shapes are
shapely geometries in (north, east) [m].
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # the engine builds the shapes; the vocabulary only names their type
    from shapely.geometry import Polygon
    from shapely.geometry.base import BaseGeometry


@dataclass(frozen=True, slots=True)
class IntruderTrack:
    """Another aircraft as tracked (ADS-B / cooperative report / LiDAR track filter).

    ``pos_cov`` and ``vel_cov`` are 3x3 NED covariances [m^2], [m^2/s^2]; ``radius_m`` is the
    body radius; ``cooperative`` is true for UAS that exchange position notifications."""

    id: str
    t: float
    pos_ned: np.ndarray
    vel_ned: np.ndarray
    radius_m: float = 1.0
    pos_cov: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    vel_cov: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    cooperative: bool = False


@dataclass(frozen=True, slots=True)
class SphereThreat:
    """A spherical threat (seed 001): centre NED [m] at time ``t``, constant velocity [m/s]."""

    id: str
    t: float
    center_ned: np.ndarray
    radius_m: float
    vel_ned: np.ndarray = field(default_factory=lambda: np.zeros(3))
    center_cov: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))


@dataclass(frozen=True, slots=True)
class PrismObstacle:
    """A static obstacle known from the map: a footprint extruded between two heights
    (buildings, no-fly volumes). ``up_min_m``/``up_max_m``: heights above the origin [m]."""

    id: str
    footprint: BaseGeometry
    up_min_m: float
    up_max_m: float
    hard: bool = True


@dataclass(frozen=True, slots=True)
class Geofence:
    """Where the vehicle must stay (``keep_in``) or must not go, with an altitude band."""

    id: str
    area: Polygon
    up_min_m: float
    up_max_m: float
    keep_in: bool = True


@dataclass(frozen=True, slots=True)
class StormSnapshot:
    """Storm cells valid at time ``t``: polygons in (north, east) [m], optional velocity of
    each cell [m/s] (N, E) for extrapolation, optional vertical extent of each cell
    ``extents_up_m`` (N, 2) = [base, top] heights above the origin [m]: a cell is the prism of
    its polygon between them (-inf base: from the ground; None: every cell from the ground up
    without a top)."""

    t: float
    cells: tuple[Polygon, ...]
    velocities_ne: np.ndarray | None = None
    extents_up_m: np.ndarray | None = None

    def extents(self) -> np.ndarray:
        """[base, top] heights above the origin [m] of every cell (N, 2), -inf/inf if unbounded."""
        if self.extents_up_m is None:
            return np.tile([-np.inf, np.inf], (len(self.cells), 1))
        return np.asarray(self.extents_up_m, float).reshape(len(self.cells), 2)


@dataclass(frozen=True, slots=True)
class ScanPattern:
    """A scanning LiDAR's homogeneous ray grid [deg]: azimuth from the sensor's x axis, positive
    to the right (FRD), elevation positive up; a full azimuth turn does not repeat its end."""

    azimuth_min_deg: float
    azimuth_max_deg: float
    azimuth_step_deg: float
    elevation_min_deg: float
    elevation_max_deg: float
    elevation_step_deg: float

    def directions(self) -> np.ndarray:
        """Unit ray directions (N, 3) in the sensor frame (x forward, y right, z down),
        elevation-major."""
        full = self.azimuth_max_deg - self.azimuth_min_deg >= 360.0 - 1e-9
        n_az = round((self.azimuth_max_deg - self.azimuth_min_deg) / self.azimuth_step_deg) + (0 if full else 1)
        n_el = round((self.elevation_max_deg - self.elevation_min_deg) / self.elevation_step_deg) + 1
        az = np.radians(self.azimuth_min_deg + self.azimuth_step_deg * np.arange(n_az))
        el = np.radians(self.elevation_min_deg + self.elevation_step_deg * np.arange(n_el))
        el, az = (a.ravel() for a in np.meshgrid(el, az, indexing="ij"))
        return np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), -np.sin(el)], axis=1)


@dataclass(frozen=True, slots=True)
class LidarScan:
    """One LiDAR sweep: sensor position NED [m], unit ray directions (N, 3) NED, measured ranges
    (N,) [m] with ``hit`` (N,) false where nothing returned within ``max_range_m``. A sensor's
    scan also carries how it was made (what the log stores instead of the directions):
    ``pattern``, ``rotation`` (3, 3) sensor -> NED with ``directions_ned = pattern.directions()
    @ rotation.T``, and ``range_resolution_m`` [m] (every hit range a whole multiple of it)."""

    t: float
    origin_ned: np.ndarray
    directions_ned: np.ndarray
    ranges_m: np.ndarray
    hit: np.ndarray
    max_range_m: float
    pattern: ScanPattern | None = None
    rotation: np.ndarray | None = None
    range_resolution_m: float | None = None
