"""Weather case (spec §7.5, tab. 6.9): a storm cell of the weather service as the rules see it.

For small UAS the cell's body is a hard constraint and a band of ``margin`` around it a soft one.
A cell with zero velocity is *static* and handled like a roundabout (passed on the right of its
centre); a moving one like an intruder (its body and band move with it). Frames and units: z-up
GCF (ENU) [m], horizontal velocity [m/s], sim seconds [s]; the nowcast has no vertical extent,
so a cell covers every altitude.

With a central UTM authority that owns the weather feed (scenario ``utm.weather``) the weather
cases come in its directives: :func:`crossing` picks the cells a UAS's filed route crosses.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import shapely
import shapely.affinity
from shapely.geometry import Polygon

from avoidance.reachset.frames import ne_to_gcf_xy
from sim.core.threats import StormSnapshot


@dataclass(frozen=True, slots=True)
class WeatherCase:
    """One cell: ``body`` polygon in GCF (x east, y north) [m] at ``t`` [s], soft band ``margin``
    [m], horizontal ``velocity`` GCF [m/s]."""

    id: str
    t: float
    body: Polygon
    margin: float
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(2))

    @property
    def moving(self) -> bool:
        return bool(np.any(self.velocity != 0.0))

    @property
    def centre(self) -> np.ndarray:
        """The body's centroid at ``t``, GCF [m] (z = 0)."""
        c = self.body.centroid
        return np.array([c.x, c.y, 0.0])

    @property
    def radius(self) -> float:
        """Largest distance of a body vertex from :attr:`centre` [m]."""
        xy = shapely.get_coordinates(self.body)
        return float(np.max(np.hypot(xy[:, 0] - self.centre[0], xy[:, 1] - self.centre[1])))

    def moved(self, t: float) -> Polygon:
        """The body at time ``t`` [s] (moved with the velocity)."""
        dx, dy = self.velocity * (t - self.t)
        return shapely.affinity.translate(self.body, float(dx), float(dy))

    def record(self) -> dict:
        """JSON-ready values (GCF)."""
        return {
            "id": self.id,
            "t": self.t,
            "centre_enu": self.centre.tolist(),
            "margin_m": self.margin,
            "velocity_enu": self.velocity.tolist(),
            "moving": self.moving,
            "body_enu": shapely.get_coordinates(self.body).tolist(),
        }

    @classmethod
    def from_record(cls, r: dict) -> WeatherCase:
        """The case of a :meth:`record` (a logged directive's)."""
        return cls(r["id"], r["t"], Polygon(r["body_enu"]), r["margin_m"], np.asarray(r["velocity_enu"], float))


def crossing(cases: list[WeatherCase], route: np.ndarray, horizon: float) -> list[WeatherCase]:
    """The ``cases`` whose body grown by its band the ``route`` (GCF polyline (K, 2+) [m], K >= 1)
    touches; a moving body is swept over the next ``horizon`` [s] (its hull from ``t`` to
    ``t + horizon``)."""
    path = shapely.LineString(route[:, :2]) if len(route) > 1 else shapely.Point(route[0, :2])
    out = []
    for w in cases:
        body = shapely.convex_hull(shapely.union(w.body, w.moved(w.t + horizon))) if w.moving else w.body
        if body.buffer(w.margin).intersects(path):
            out.append(w)
    return out


def weather_cases(storms: list[StormSnapshot], t: float, margin: float, up_m: float = 0.0) -> list[WeatherCase]:
    """The cells of the newest snapshot not after ``t`` [s] (the first one if all are later) as
    weather cases with the soft band ``margin`` [m]: those whose prism, grown by ``margin`` up
    and down, holds the own height ``up_m`` [m above the origin]; a cell flown over (or under)
    by more than the band is no case. Ids are the cells' indices in the snapshot."""
    usable = sorted((s for s in storms if s.t <= t), key=lambda s: s.t) or sorted(storms, key=lambda s: s.t)[:1]
    if not usable:
        return []
    snap = usable[-1]
    vel = np.zeros((len(snap.cells), 2)) if snap.velocities_ne is None else ne_to_gcf_xy(snap.velocities_ne)
    ext = snap.extents()
    near = (ext[:, 0] - margin <= up_m) & (up_m <= ext[:, 1] + margin)
    return [
        WeatherCase(f"cell{k}", snap.t, shapely.transform(c, ne_to_gcf_xy), margin, np.asarray(v, float))
        for k, (c, v) in enumerate(zip(snap.cells, vel, strict=True))
        if near[k]
    ]
