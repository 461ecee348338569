"""Crashes found from the TRUE states: ground, obstacles, other vehicles and traffic objects.

- **ground** (flat, at the origin altitude), after EVERY plant step (:class:`GroundWatch`; a hard
  impact can compress the contact springs and throw the vehicle back up within one check
  interval): the airframe's contact hull (``sim.hull``, the JSBSim model's contact points) placed
  with the true CG height and attitude, evaluated only within the hull's reach of the ground (one
  property read per step otherwise). A vehicle crashes when a hull point that is not landing gear
  touches (it is on its side or back), or when its gear first touches while the sink rate at the
  step before contact exceeded the airframe's ``crash_sink_mps``; a gentler touchdown is a landing.

The rest is checked at a fixed rate (the world's contact rate, :class:`ContactMonitor`); between
two checks every body is taken to move in a straight line, so contacts between checks are not
missed (swept tests):

- **obstacles** (prisms between two heights): the vehicle's sphere (``radius_m``) swept from its
  last checked position to its current one meets the footprint (shapely ``dwithin`` on a
  ``STRtree``) within the prism's height band (the band of the swept segment, widened by the
  radius).
- **vehicles and objects**: two spheres whose closest approach over the interval, with both
  moving linearly, is below the sum of their radii (candidate pairs: every vehicle pair and
  vehicle-object pair within reach, found by direct distances when there are at most
  ``_DIRECT_PAIRS`` of them, else from a k-d tree).

Frames and units: local-level NED from the scenario origin [m, m/s]; heights up = -D [m].
Impact speed [m/s]: the vehicle's speed relative to what it hit (for the ground, the speed just
before first contact, before the gear's springs act).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import shapely
from scipy.spatial import cKDTree

from sim.core.constants import FT
from sim.core.threats import PrismObstacle
from sim.hull import Hull
from sim.jsbsim_plant import JSBSimPlant

_DIRECT_PAIRS = 4096  # vehicle-body pairs up to which all distances are computed (no k-d tree)
NEAR_GROUND_M = 1.0  # [m] beyond the hull's reach: closer, the hull is placed every step
_WATCH_PROPS = (
    "position/h-agl-ft",
    "attitude/phi-rad",
    "attitude/theta-rad",
    "velocities/v-north-fps",
    "velocities/v-east-fps",
    "velocities/v-down-fps",
)


@dataclass(frozen=True, slots=True)
class Crash:
    """``vehicle`` hit ``hit`` (``"ground"``, an obstacle id, a vehicle name or an object id;
    ``kind`` says which) at sim time ``t`` [s] at ``impact_speed_mps`` [m/s], at ``pos_ned`` [m]."""

    t: float
    vehicle: str
    kind: str  # "ground" | "obstacle" | "vehicle" | "object"
    hit: str
    impact_speed_mps: float
    pos_ned: tuple[float, float, float]

    def describe(self) -> str:
        """What was hit and how fast, e.g. ``hit obstacle 'tower' at 5.02 m/s``."""
        what = "the ground" if self.kind == "ground" else f"{self.kind} {self.hit!r}"
        return f"hit {what} at {self.impact_speed_mps:.2f} m/s"

    def record(self) -> dict:
        return {
            "t": self.t,
            "vehicle": self.vehicle,
            "kind": self.kind,
            "hit": self.hit,
            "impact_speed_mps": self.impact_speed_mps,
            "pos_ned": list(self.pos_ned),
        }


@dataclass(frozen=True, slots=True)
class Bodies:
    """Moving spheres at one check: ids, positions and velocities NED (N, 3) [m, m/s], radii (N,) [m]."""

    ids: list[str]
    pos: np.ndarray
    vel: np.ndarray
    radius: np.ndarray


class GroundWatch:
    """Ground contact of one vehicle with contact ``hull`` and sink-rate limit ``crash_sink_mps``
    [m/s], fed the true state after every plant step; ``crash`` holds (t [s], impact speed [m/s])
    once it crashed, ``crash_pos`` the true position NED [m] then (when watching a plant)."""

    def __init__(self, hull: Hull, crash_sink_mps: float):
        self.hull = hull
        self.limit = float(crash_sink_mps)
        self.near_m = hull.reach_m + NEAR_GROUND_M
        self.crash: tuple[float, float] | None = None
        self.crash_pos: np.ndarray | None = None
        self._prev_vel: np.ndarray | None = None  # velocity NED at the previous near-ground step
        self._touching = False

    def observe(self, t: float, up_cg_m: float, roll: float, pitch: float, vel_ned: np.ndarray) -> None:
        """The state after one step: CG height above the ground [m], attitude [rad], velocity NED [m/s]."""
        if self.crash is not None:
            return
        if up_cg_m > self.near_m:
            self._prev_vel, self._touching = None, False
            return
        touch, structure = self.hull.touching(up_cg_m, roll, pitch)
        before = vel_ned if self._prev_vel is None else self._prev_vel
        first = touch and not self._touching
        if structure or (first and before[2] > self.limit):
            self.crash = (t, float(np.linalg.norm(before if first else vel_ned)))
        self._prev_vel, self._touching = vel_ned, touch

    def attach(self, plant: JSBSimPlant) -> None:
        """Watch ``plant``'s true state after each of its steps (its terrain is the ground)."""
        agl, phi, theta, vn, ve, vd = (n.get_double_value for n in plant.property_nodes(_WATCH_PROPS))
        near_ft = self.near_m / FT

        def after_step() -> None:
            h = agl()
            if h <= near_ft and self.crash is None:
                self.observe(plant.time, h * FT, phi(), theta(), np.array([vn(), ve(), vd()]) * FT)
                if self.crash is not None:
                    self.crash_pos = plant.truth().pos_ned.copy()
            elif self._touching or self._prev_vel is not None:
                self._prev_vel, self._touching = None, False

        plant.after_step = after_step


class ContactMonitor:
    """Finds the crashes of ``names`` (vehicles with sphere ``radius_m`` (N,) and ground watches)
    against the ground, ``obstacles`` and each other; call :meth:`check` at a fixed rate."""

    def __init__(
        self, names: list[str], radius_m: np.ndarray, ground: list[GroundWatch], obstacles: list[PrismObstacle]
    ):
        self.names = list(names)
        self.radius = np.asarray(radius_m, float)
        self.ground = ground
        self._reported = np.zeros(len(self.names), bool)
        self.obstacles = obstacles
        self._tree = shapely.STRtree([o.footprint for o in obstacles]) if obstacles else None
        self._band = np.array([(o.up_min_m, o.up_max_m) for o in obstacles], float).reshape(-1, 2)
        self._bounds = np.array([o.footprint.bounds for o in obstacles], float).reshape(-1, 4)
        self._prev: dict[str, np.ndarray] = {}  # last checked position of every body

    def check(self, t: float, pos: np.ndarray, vel: np.ndarray, others: Bodies) -> list[Crash]:
        """Crashes at this check: ground contacts the watches found since the last check, and
        the vehicles' true positions and velocities NED (N, 3) [m, m/s] against the obstacles
        and the other bodies (traffic objects) now."""
        pos, vel = np.asarray(pos, float), np.asarray(vel, float)
        prev = np.array([self._prev.get(n, p) for n, p in zip(self.names, pos, strict=True)])
        crashes = self._ground(pos)
        crashes += self._obstacles(t, prev, pos, vel)
        crashes += self._bodies(t, prev, pos, vel, others)
        self._prev = dict(zip(self.names + others.ids, np.vstack([pos, others.pos]), strict=True))
        return crashes

    def _ground(self, pos: np.ndarray) -> list[Crash]:
        out = []
        for i, w in enumerate(self.ground):
            if w.crash is not None and not self._reported[i]:
                self._reported[i] = True
                at = pos[i] if w.crash_pos is None else w.crash_pos
                out.append(self._crash(w.crash[0], i, "ground", "ground", w.crash[1], at))
        return out

    def _obstacles(self, t: float, prev: np.ndarray, pos: np.ndarray, vel: np.ndarray) -> list[Crash]:
        if self._tree is None:
            return []
        r = self.radius[:, None]
        lo = np.minimum(prev, pos) - r  # swept boxes widened by the radius, (N, 3)
        hi = np.maximum(prev, pos) + r
        b, band = self._bounds, self._band
        near = (  # box overlap with the prisms' bounding boxes (N, M): the exact test only for these
            (lo[:, None, 0] <= b[None, :, 2])
            & (hi[:, None, 0] >= b[None, :, 0])
            & (lo[:, None, 1] <= b[None, :, 3])
            & (hi[:, None, 1] >= b[None, :, 1])
            & (-hi[:, None, 2] <= band[None, :, 1])
            & (-lo[:, None, 2] >= band[None, :, 0])
        )
        cand = np.flatnonzero(near.any(axis=1))
        if not len(cand):
            return []
        segments = shapely.linestrings(np.stack([prev[cand, :2], pos[cand, :2]], axis=1))
        k, obs = self._tree.query(segments, predicate="dwithin", distance=self.radius[cand])
        veh = cand[k]
        hit = near[veh, obs]
        speed = np.linalg.norm(vel, axis=1)
        first: dict[int, int] = {}
        for i, k in zip(veh[hit].tolist(), obs[hit].tolist(), strict=True):
            first.setdefault(i, k)  # one crash per vehicle: the first obstacle in scenario order
        return [self._crash(t, i, "obstacle", self.obstacles[k].id, speed[i], pos[i]) for i, k in sorted(first.items())]

    def _bodies(self, t: float, prev: np.ndarray, pos: np.ndarray, vel: np.ndarray, others: Bodies) -> list[Crash]:
        n = len(self.names)
        if n + len(others.ids) < 2:
            return []
        ids = self.names + others.ids
        p1 = np.vstack([pos, others.pos])
        o_prev = [self._prev.get(i, p) for i, p in zip(others.ids, others.pos, strict=True)]
        p0 = np.vstack([prev, np.reshape(o_prev, (-1, 3))])
        v = np.vstack([vel, others.vel])
        r = np.concatenate([self.radius, others.radius])
        reach = 2.0 * r.max() + 2.0 * np.linalg.norm(p1 - p0, axis=1).max()
        i, j = _pairs_within(p1, n, reach)
        if not len(i):
            return []
        d0, d1 = p0[i] - p0[j], p1[i] - p1[j]
        dd = d1 - d0
        s = np.clip(-np.einsum("ij,ij->i", d0, dd) / np.maximum(np.einsum("ij,ij->i", dd, dd), 1e-12), 0.0, 1.0)
        touch = np.linalg.norm(d0 + s[:, None] * dd, axis=1) <= r[i] + r[j]
        out = []
        for a, b in zip(i[touch].tolist(), j[touch].tolist(), strict=True):
            speed = float(np.linalg.norm(v[a] - v[b]))
            out.append(self._crash(t, a, "vehicle" if b < n else "object", ids[b], speed, pos[a]))
            if b < n:
                out.append(self._crash(t, b, "vehicle", ids[a], speed, pos[b]))
        return out

    def _crash(self, t: float, i: int, kind: str, hit: str, speed: float, p: np.ndarray) -> Crash:
        """Vehicle ``i``'s crash at position ``p`` NED [m]."""
        return Crash(t, self.names[i], kind, hit, float(speed), (float(p[0]), float(p[1]), float(p[2])))


def _pairs_within(pos: np.ndarray, n: int, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs ``i < j`` with ``i < n`` (at least one vehicle) of the positions ``pos``
    (M, 3) [m] at most ``reach`` [m] apart, ordered by ``(i, j)``."""
    m = len(pos)
    if n * m <= _DIRECT_PAIRS:
        i, j = _vehicle_pairs(m, n)
        d = pos[i] - pos[j]
        near = np.einsum("ij,ij->i", d, d) <= reach * reach
        return i[near], j[near]
    pairs = cKDTree(pos).query_pairs(reach, output_type="ndarray")
    pairs = pairs[pairs[:, 0] < n]
    pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
    return pairs[:, 0], pairs[:, 1]


@lru_cache(maxsize=64)
def _vehicle_pairs(m: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """All index pairs ``i < j < m`` with ``i < n``, ordered by ``(i, j)``."""
    i, j = np.triu_indices(m, 1)
    keep = i < n
    return i[keep], j[keep]
