"""Two-axis rotary LiDAR ray-cast against the world's prism obstacles (exact geometry).

Scan pattern (avoidance-reach-set.md §5.1, §3.3, A-12, A-21): a homogeneous grid of rays with
constant angular steps, azimuth [-180, 180) deg and elevation [-30, 30] deg in 1 deg steps by
default, range 10 m (the worst-case sensor field of the avoidance grid). Azimuth is measured
from the sensor's x axis, positive to the right (FRD); elevation positive up. The sensor frame
is either ``level`` (rotated by yaw only: a stabilised scanner, the avoidance grid's frame,
A-12) or ``body`` (strapped down: roll and pitch tilt the scan).

Geometry: a :class:`sim.core.threats.PrismObstacle` is its shapely footprint (north, east)
extruded from ``up_min_m`` to ``up_max_m``; a ray's first entry is the nearest of its crossings
of the side walls (2-D ray/edge intersections, all rings of the footprint) within the height
band and of the top/bottom faces inside the footprint. Obstacles whose footprint lies beyond the
range are skipped, and only rays within an obstacle's azimuth sector are tested. A sensor inside
an obstacle sees nothing of it.

Ray casting uses the *true* pose; the returns are expressed in the sensor frame and turned into
a NED :class:`~sim.core.threats.LidarScan` with the *estimated* pose
(:meth:`LidarReturns.to_scan`), so planners never see truth.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import shapely
from pydantic import Field, model_validator

from sim.core.frames import euler_to_dcm
from sim.core.state import VehicleState
from sim.core.threats import LidarScan, PrismObstacle, ScanPattern
from sim.sensors.base import SampledSensor, SensorConfig
from sim.sensors.channel import Channel, ChannelConfig
from sim.sensors.truth import TruthSample


class LidarConfig(SensorConfig):
    """Angles in degrees (people-facing config), range in metres."""

    rate_hz: float = Field(10.0, gt=0.0)
    max_range_m: float = Field(10.0, gt=0.0)
    azimuth_min_deg: float = Field(-180.0, ge=-180.0)
    azimuth_max_deg: float = Field(180.0, le=180.0)
    azimuth_step_deg: float = Field(1.0, gt=0.0)
    elevation_min_deg: float = Field(-30.0, ge=-90.0)
    elevation_max_deg: float = Field(30.0, le=90.0)
    elevation_step_deg: float = Field(1.0, gt=0.0)
    frame: Literal["level", "body"] = "level"
    range_error: ChannelConfig = ChannelConfig(noise_std=0.02)
    return_probability: float = Field(1.0, gt=0.0, le=1.0)
    range_resolution_m: float = Field(0.001, gt=0.0)  # reported ranges are whole multiples of it

    @model_validator(mode="after")
    def _check(self):
        if self.azimuth_max_deg <= self.azimuth_min_deg:
            raise ValueError("azimuth_max_deg must exceed azimuth_min_deg")
        if self.elevation_max_deg < self.elevation_min_deg:
            raise ValueError("elevation_max_deg must not be below elevation_min_deg")
        return self

    def pattern(self) -> ScanPattern:
        return ScanPattern(
            self.azimuth_min_deg,
            self.azimuth_max_deg,
            self.azimuth_step_deg,
            self.elevation_min_deg,
            self.elevation_max_deg,
            self.elevation_step_deg,
        )

    def ray_directions(self) -> np.ndarray:
        """Unit ray directions (N, 3) in the sensor frame (x forward, y right, z down).
        A full turn (-180..180) does not repeat the closing azimuth."""
        return self.pattern().directions()


@dataclass(frozen=True, slots=True)
class LidarReturns:
    """One sweep in the sensor frame: ``ranges_m`` (N,) [m], NaN where nothing returned, rays
    ``directions_sensor`` of ``pattern``; ranges are reported in whole ``range_resolution_m``."""

    t: float
    ranges_m: np.ndarray
    directions_sensor: np.ndarray
    max_range_m: float
    frame: str
    pattern: ScanPattern
    range_resolution_m: float

    def to_scan(self, estimate: VehicleState) -> LidarScan:
        """NED scan placed at the *estimated* pose (position; yaw, or full attitude), ranges
        rounded to the resolution."""
        roll, pitch, yaw = estimate.euler
        r = euler_to_dcm(0.0, 0.0, yaw) if self.frame == "level" else euler_to_dcm(roll, pitch, yaw)
        hit = np.isfinite(self.ranges_m)
        res = self.range_resolution_m
        return LidarScan(
            t=self.t,
            origin_ned=np.array(estimate.pos_ned, float),
            directions_ned=self.directions_sensor @ r.T,
            ranges_m=np.where(hit, np.rint(self.ranges_m / res) * res, self.max_range_m),
            hit=hit,
            max_range_m=self.max_range_m,
            pattern=self.pattern,
            rotation=r,
            range_resolution_m=res,
        )


@dataclass(frozen=True, slots=True)
class _Prism:
    geom: object
    a: np.ndarray  # edge starts (E, 2) north, east
    e: np.ndarray  # edge vectors (E, 2)
    xy: np.ndarray  # vertices (V, 2)
    up_min: float
    up_max: float


def _prepare(ob: PrismObstacle) -> _Prism:
    geom = ob.footprint
    shapely.prepare(geom)
    starts, vecs = [], []
    for ring in shapely.get_rings(shapely.get_parts(geom)):
        c = shapely.get_coordinates(ring)
        starts.append(c[:-1])
        vecs.append(c[1:] - c[:-1])
    return _Prism(
        geom,
        np.concatenate(starts),
        np.concatenate(vecs),
        shapely.get_coordinates(geom),
        float(ob.up_min_m),
        float(ob.up_max_m),
    )


def cast_rays(origin_ned: np.ndarray, dirs_ned: np.ndarray, prisms: Sequence[_Prism], max_range: float) -> np.ndarray:
    """Exact first-hit range [m] of each unit ray (N, 3) NED from ``origin_ned``; NaN = no hit
    within ``max_range``."""
    o_n, o_e, o_up = float(origin_ned[0]), float(origin_ned[1]), -float(origin_ned[2])
    best = np.full(len(dirs_ned), np.inf)
    pt = shapely.Point(o_n, o_e)
    az_all = np.arctan2(dirs_ned[:, 1], dirs_ned[:, 0])
    for pr in prisms:
        if shapely.distance(pr.geom, pt) > max_range:
            continue
        inside_h = shapely.contains_xy(pr.geom, o_n, o_e)
        if inside_h and pr.up_min <= o_up <= pr.up_max:
            continue
        idx = np.arange(len(dirs_ned))
        if not inside_h:  # rays within the footprint's azimuth sector only
            ang = np.arctan2(pr.xy[:, 1] - o_e, pr.xy[:, 0] - o_n)
            mid = math.atan2(np.sin(ang).mean(), np.cos(ang).mean())
            rel = np.angle(np.exp(1j * (ang - mid)))
            d = np.angle(np.exp(1j * (az_all - mid)))
            if rel.max() - rel.min() < math.pi - 1e-6:  # else: wraps around the sensor, test all
                idx = np.flatnonzero((d >= rel.min() - 1e-9) & (d <= rel.max() + 1e-9))
                if idx.size == 0:
                    continue
        d = dirs_ned[idx]
        dn, de, du = d[:, 0:1], d[:, 1:2], -d[:, 2:3]
        # side walls: o + s d_h = a + u e
        an, ae = pr.a[:, 0] - o_n, pr.a[:, 1] - o_e
        en, ee = pr.e[:, 0], pr.e[:, 1]
        den = dn * ee - de * en
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (an * ee - ae * en) / den
            u = (an * de - ae * dn) / den
            up = o_up + s * du
        ok = (den != 0) & (s >= 0) & (u >= 0) & (u <= 1) & (up >= pr.up_min) & (up <= pr.up_max)
        s_wall = np.where(ok, s, np.inf).min(axis=1)
        # top and bottom faces
        s_cap = np.full(len(idx), np.inf)
        duf = du[:, 0]
        for h in (pr.up_min, pr.up_max):
            with np.errstate(divide="ignore", invalid="ignore"):
                sc = (h - o_up) / duf
            cand = np.flatnonzero((sc >= 0) & (sc <= max_range) & (sc < s_cap))
            if cand.size:
                inside = shapely.contains_xy(pr.geom, o_n + sc[cand] * d[cand, 0], o_e + sc[cand] * d[cand, 1])
                s_cap[cand[inside]] = sc[cand[inside]]
        best[idx] = np.minimum(best[idx], np.minimum(s_wall, s_cap))
    return np.where(best <= max_range, best, np.nan)


class Lidar(SampledSensor[LidarReturns]):
    """Output vector: one range per ray [m], NaN for no return (faults: ``bias_step`` with a
    scalar adds to every range, ``stuck`` repeats the last sweep, ``dropout`` drops sweeps)."""

    cfg: LidarConfig

    name = "lidar"

    def __init__(self, cfg: LidarConfig, obstacles: Sequence[PrismObstacle], rng: np.random.Generator):
        super().__init__(cfg, rng)
        self._pattern = cfg.pattern()
        self.directions = self._pattern.directions()
        self.dim = len(self.directions)
        self.faults.dim = self.dim
        self._prisms = [_prepare(o) for o in obstacles]
        self._err = Channel(cfg.range_error, self.dim, rng)

    def _measure(self, truth: TruthSample, dt: float) -> np.ndarray:
        roll, pitch, yaw = truth.state.euler
        c = self.cfg
        r = euler_to_dcm(0.0, 0.0, yaw) if c.frame == "level" else euler_to_dcm(roll, pitch, yaw)
        true = cast_rays(truth.state.pos_ned, self.directions @ r.T, self._prisms, c.max_range_m)
        y = self._err.apply(np.nan_to_num(true, nan=0.0), dt)
        y = np.where(np.isnan(true), np.nan, np.clip(y, 0.0, c.max_range_m))
        if c.return_probability < 1.0:
            y[self.rng.random(self.dim) >= c.return_probability] = np.nan
        return y

    def _package(self, t: float, y: np.ndarray) -> LidarReturns:
        c = self.cfg
        return LidarReturns(t, y, self.directions, c.max_range_m, c.frame, self._pattern, c.range_resolution_m)
