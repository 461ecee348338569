"""Threat spheres as the planner core sees them (spec §1.2, §3.1, §4.2).

Frame: local ENU z-up [m, m/s]. Time τ [s] runs from the evading instant (τ = 0), i.e. a threat's
``p`` is its predicted centre when the UAV is at the evading point. Motion is constant-velocity.
Uncertainty is folded into the radius: ``radius`` [m] at τ = 0 and ``growth`` [m/s] added per
second of prediction (k_σ·σ_v), see :func:`inflate`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def _vec3(name: str, v) -> np.ndarray:
    a = np.asarray(v, float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be a finite 3-vector, got {v!r}")
    return a


@dataclass(frozen=True, slots=True)
class Threat:
    """Sphere of ``radius`` [m] centred at ``p`` [m] at τ = 0, moving at ``v`` [m/s]."""

    id: str
    p: np.ndarray
    v: np.ndarray
    radius: float
    growth: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "p", _vec3(f"threat {self.id!r} position", self.p))
        object.__setattr__(self, "v", _vec3(f"threat {self.id!r} velocity", self.v))
        if not (np.isfinite(self.radius) and self.radius > 0):
            raise ValueError(f"threat {self.id!r}: radius must be finite and > 0, got {self.radius!r}")
        if not (np.isfinite(self.growth) and self.growth >= 0):
            raise ValueError(f"threat {self.id!r}: growth must be finite and >= 0, got {self.growth!r}")

    @property
    def is_static(self) -> bool:
        return not np.any(self.v)

    def at(self, tau: float) -> np.ndarray:
        """Predicted centre at time τ [s]."""
        return self.p + self.v * tau


def sigma_max(cov: np.ndarray | None) -> float:
    """sqrt of the largest eigenvalue of a 3x3 covariance (0 for None); rejects bad matrices."""
    if cov is None:
        return 0.0
    c = np.asarray(cov, float)
    if c.shape != (3, 3) or not np.all(np.isfinite(c)) or not np.allclose(c, c.T, atol=1e-9 * (1 + np.abs(c).max())):
        raise ValueError(f"covariance must be a finite symmetric 3x3 matrix, got {cov!r}")
    lam = np.linalg.eigvalsh(c)
    if lam[0] < -1e-9 * (1.0 + abs(lam[-1])):
        raise ValueError("covariance must be positive semi-definite")
    return float(np.sqrt(max(lam[-1], 0.0)))


def inflate(
    radius: float, pos_cov: np.ndarray | None, vel_cov: np.ndarray | None, k_sigma: float, age_s: float
) -> tuple[float, float]:
    """(radius at τ = 0, growth rate) for a track whose estimate is ``age_s`` [s] old at τ = 0:
    R + k_σ·(σ_p + σ_v·age) and k_σ·σ_v, σ = sqrt(λ_max) of the covariances (spec §3.1, G27)."""
    if k_sigma == 0.0:
        return float(radius), 0.0
    sp, sv = sigma_max(pos_cov), sigma_max(vel_cov)
    return float(radius + k_sigma * (sp + sv * max(age_s, 0.0))), float(k_sigma * sv)


@dataclass(frozen=True, slots=True)
class ThreatArrays:
    """Threats stacked for vectorised checks: ``p``, ``v`` (J, 3), ``radius``, ``growth`` (J,),
    ``static`` (J,) bool."""

    p: np.ndarray
    v: np.ndarray
    radius: np.ndarray
    growth: np.ndarray
    static: np.ndarray

    @classmethod
    def of(cls, threats: list[Threat] | tuple[Threat, ...]) -> ThreatArrays:
        if not threats:
            z = np.zeros((0, 3))
            return cls(z, z.copy(), np.zeros(0), np.zeros(0), np.zeros(0, bool))
        v = np.array([t.v for t in threats])
        return cls(
            np.array([t.p for t in threats]),
            v,
            np.array([t.radius for t in threats]),
            np.array([t.growth for t in threats]),
            ~np.any(v != 0.0, axis=1),
        )

    def __len__(self) -> int:
        return len(self.radius)

    def collision_paths(self, durations: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Straight collision paths over ``durations`` (J,) [s] (spec §4.2): start (J, 3), end
        (J, 3) and the radius (J,) grown over the whole duration. Static threats: zero length."""
        return self.p, self.p + self.v * durations[:, None], self.radius + self.growth * durations
