"""Synthetic convective weather: the true storm field and the nowcasts issued to the vehicles.

The field is MPTP's seeded storm generator (``sim.storm_synthetic.StormField``: cells that
drift, grow, decay, split and merge) in the local (north, east) plane [m], plus the scenario's
scripted cells (fixed polygons drifting at constant velocity). Every
``nowcast_period`` a nowcast of the next ``horizon`` is issued: what planners see
(``Threats.storms``); the truth is for logging and metrics only. Or a series of nowcast files
(:class:`NowcastSeries`), each issued at its first step's time.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import Polygon

from sim import scenario as sc
from sim.core.threats import StormSnapshot
from sim.geodesy import GeoPoint
from sim.nowcast_files import load_series
from sim.storm_synthetic import StormField


@dataclass
class ScriptedStormField(StormField):
    """A storm field with extra ``scripted`` cells: (polygon (north, east) [m] at t = 0,
    velocity (2,) [m/s], vertical extent (2,) [base, top] above the origin [m]) triples that
    neither grow, decay nor split."""

    scripted: tuple = ()

    def cell_shapes(self, t: float) -> tuple[list[Polygon], np.ndarray, np.ndarray]:
        shapes, vel, ext = super().cell_shapes(t)
        shapes = shapes + [shapely.affinity.translate(p, *(v * t)) for p, v, _ in self.scripted]
        vel = np.vstack([vel.reshape(-1, 2)] + [v for _, v, _ in self.scripted]).reshape(-1, 2)
        return shapes, vel, np.vstack([ext.reshape(-1, 2)] + [e for _, _, e in self.scripted]).reshape(-1, 2)


class NowcastSeries:
    """Weather from a series of nowcast files (``[weather] nowcast_files``): the nowcast issued at
    t is the latest file whose first step is at or before t; the truth is that nowcast's first
    step (the analysis) with its cells moved by their velocities since then."""

    def __init__(self, series: list[list[StormSnapshot]]):
        self.series = series
        self.issued = np.array([nc[0].t for nc in series])

    def latest(self, t: float) -> int:
        """Index of the nowcast in force at ``t`` [s] (the first one before its issue)."""
        return max(int(np.searchsorted(self.issued, t + 1e-9, side="right")) - 1, 0)

    def truth(self, t: float) -> StormSnapshot:
        a = self.series[self.latest(t)][0]
        v = np.zeros((len(a.cells), 2)) if a.velocities_ne is None else np.asarray(a.velocities_ne, float)
        dt = max(t - a.t, 0.0)
        return StormSnapshot(
            t,
            tuple(shapely.affinity.translate(c, *(vk * dt)) for c, vk in zip(a.cells, v, strict=True)),
            a.velocities_ne,
            a.extents_up_m,
        )


class WeatherService:
    def __init__(self, cfg: sc.Weather, seed: int, origin: GeoPoint | None = None):
        """``origin``: the scenario's, for nowcast files in WGS84 and the cells' heights (altitudes
        MSL in the scenario and the files, heights above the origin in the snapshots)."""
        self.cfg = cfg
        self.files = NowcastSeries(load_series(cfg.nowcast_files, origin)) if cfg.nowcast_files else None
        alt0 = 0.0 if origin is None else origin.alt_m
        self.field = ScriptedStormField(
            scripted=tuple(
                (Polygon(c.points), np.array([c.drift_north, c.drift_east]), np.array(c.extent_up(alt0)))
                for c in cfg.storm
            ),
            extent_up_m=cfg.extent_up(alt0),
            seed=seed if cfg.seed is None else cfg.seed,
            births_after_t0=cfg.pop_up,
            n_cells=cfg.cells,
            size_m=(cfg.size, cfg.size),
            mean_velocity=(cfg.drift_north, cfg.drift_east),
            speed_spread=cfg.drift_spread,
            mean_radius_m=cfg.radius,
            split_prob=cfg.split_probability,
            life_s=cfg.life,
            centres=None if cfg.centres is None else np.array(cfg.centres, float),
        )
        self.nowcast: list[StormSnapshot] = []
        self.issued_t: float | None = None

    def update(self, t: float) -> bool:
        """Issue a nowcast if one is due at ``t`` [s]; True when a new one was issued."""
        if self.files is not None:
            k = self.files.latest(t)
            if self.issued_t == self.files.issued[k]:
                return False
            self.nowcast, self.issued_t = self.files.series[k], float(self.files.issued[k])
            return True
        if self.issued_t is not None and t < self.issued_t + self.cfg.nowcast_period - 1e-9:
            return False
        self.nowcast = self.field.nowcast(t, self.cfg.horizon, self.cfg.step)
        self.issued_t = t
        return True

    def truth(self, t: float) -> StormSnapshot:
        return self.files.truth(t) if self.files is not None else self.field.truth(t)


def storms_geojson(snapshot: StormSnapshot, to_lonlat) -> str:
    """A snapshot as a GeoJSON FeatureCollection string (lon/lat via ``to_lonlat(coords)``);
    a bounded cell's properties have its ``base_m``/``top_m`` heights above the origin [m]."""
    features = [
        {
            "type": "Feature",
            "properties": {"kind": "storm", "t": snapshot.t} | _extent_props(e),
            "geometry": {"type": "Polygon", "coordinates": [to_lonlat(list(c.exterior.coords))]},
        }
        for c, e in zip(snapshot.cells, snapshot.extents(), strict=True)
    ]
    return json.dumps({"type": "FeatureCollection", "features": features})


def _extent_props(extent: np.ndarray) -> dict[str, float]:
    return {k: float(v) for k, v in zip(("base_m", "top_m"), extent, strict=True) if np.isfinite(v)}
