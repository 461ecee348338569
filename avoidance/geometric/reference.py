"""The straight reference the geometric avoider leaves and rejoins (spec §1.2, G29).

Input and output in the harness's local NED [m]; internally local ENU z-up [m] (the one
conversion of this package, with ``sim.core.frames.ned_to_enu``). Along-track distance ``s`` [m] runs
from the first waypoint.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from avoidance.geometric.frames import unit
from sim.core.frames import enu_to_ned, ned_to_enu


@dataclass(frozen=True, slots=True)
class ReferenceLine:
    """Straight polyline ``waypoints_enu`` (M, 3) [m] flown at ``speed`` [m/s]: origin, unit
    direction ``x_hat``, ``along`` (M,) distance of each vertex from the origin, ``length`` [m]."""

    waypoints_enu: np.ndarray
    speed: float
    x_hat: np.ndarray
    along: np.ndarray

    @classmethod
    def from_ned(cls, waypoints_ned: np.ndarray, speed: float, tol_m: float = 1e-6) -> ReferenceLine:
        """Validated line: >= 2 finite vertices, strictly advancing, all within ``tol_m`` of the
        line through the first and last vertex; speed finite and > 0."""
        w = np.asarray(waypoints_ned, float)
        if w.ndim != 2 or w.shape[1] != 3 or len(w) < 2 or not np.all(np.isfinite(w)):
            raise ValueError(f"reference must be a finite (M >= 2, 3) NED array, got shape {w.shape}")
        if not (np.isfinite(speed) and speed > 0):
            raise ValueError(f"reference speed must be finite and > 0, got {speed!r}")
        enu = ned_to_enu(w)
        x_hat = unit(enu[-1] - enu[0])
        rel = enu - enu[0]
        along = rel @ x_hat
        off = np.linalg.norm(rel - along[:, None] * x_hat, axis=1)
        if off.max() > tol_m:
            raise ValueError(
                f"reference must be straight (vertex {int(off.argmax())} is {off.max():.3g} m off the line)"
            )
        if np.any(np.diff(along) <= 0):
            raise ValueError("reference vertices must advance strictly along the line")
        return cls(enu, float(speed), x_hat, along)

    @property
    def origin(self) -> np.ndarray:
        return self.waypoints_enu[0]

    @property
    def length(self) -> float:
        return float(self.along[-1])

    @property
    def velocity(self) -> np.ndarray:
        """Reference velocity, ENU [m/s]."""
        return self.x_hat * self.speed

    def project(self, p_enu: np.ndarray) -> tuple[float, float]:
        """(along-track distance clipped to [0, length], cross-track distance) of ``p_enu`` [m]."""
        rel = np.asarray(p_enu, float) - self.origin
        s = float(rel @ self.x_hat)
        return min(max(s, 0.0), self.length), float(np.linalg.norm(rel - s * self.x_hat))

    def point(self, s: float) -> np.ndarray:
        return self.origin + self.x_hat * s

    def onward(self, s: float, t_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The reference beyond along-distance ``s`` [m] reached at time ``t_s`` [s]: NED positions,
        times, vertex labels and NED velocities of the vertices after s (zero velocity at the
        last vertex). At or past the end (``s`` >= length) it is the last vertex, due at ``t_s``:
        a plan ending there still carries the last waypoint's label."""
        idx = np.flatnonzero(self.along > s + 1e-9)
        if not len(idx):
            idx = np.array([len(self.along) - 1])
        pos = enu_to_ned(self.waypoints_enu[idx])
        times = t_s + np.maximum(self.along[idx] - s, 0.0) / self.speed
        vel = np.tile(enu_to_ned(self.velocity), (len(idx), 1))
        if len(idx):
            vel[-1] = 0.0
        return pos, times, idx, vel
