"""Open-loop encounters of the thesis (spec §7.5, reconstructed geometries of §7.6, G24).

Frame: local ENU z-up [m, m/s], τ = 0 at the evading instant; the UAV starts at the origin
(unless stated) and flies its reference at 5 m/s. Used by the tests and the benchmark; the
closed-loop scenario files are built from the same geometry.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from avoidance.geometric.avoider import AvoidanceResult, plan_avoidance
from avoidance.geometric.config import GeometricConfig, VehicleParams
from avoidance.geometric.conflict import main_threat
from avoidance.geometric.threats import Threat, ThreatArrays

SPEED = 5.0


@dataclass(frozen=True, slots=True)
class Encounter:
    """UAV at ``start`` flying ``x_dir`` at ``speed`` [m/s]; ``threats[main_index]`` is the main threat."""

    start: np.ndarray
    x_dir: np.ndarray
    threats: tuple[Threat, ...]
    main_index: int = 0
    speed: float = SPEED

    def plan(self, cfg: GeometricConfig, veh: VehicleParams | None = None) -> AvoidanceResult:
        veh = veh or VehicleParams()
        ta = ThreatArrays.of(self.threats)
        ref_vel = self.speed * self.x_dir / np.linalg.norm(self.x_dir)
        main = main_threat(self.main_index, self.start, ref_vel, ta, cfg.conflict_horizon_s)
        return plan_avoidance(self.start, self.x_dir, self.speed, ta, main, cfg, veh)


def _on_course(name: str, p_c: np.ndarray, v: np.ndarray, t_c: float, radius: float) -> Threat:
    """A threat moving at ``v`` that reaches ``p_c`` at τ = ``t_c``."""
    return Threat(name, p_c - v * t_c, v, radius)


def scenario1(beta_deg: float, radius: float) -> Encounter:
    """Collision angle β [deg] (180° head-on): reference +x, p_c = (10, 0, 0), the main threat at
    5 m/s in the z = 0 plane reaching p_c at τ = 2 s."""
    b = np.radians(beta_deg)
    v = SPEED * np.array([np.cos(b), np.sin(b), 0.0])
    return Encounter(
        np.zeros(3), np.array([1.0, 0.0, 0.0]), (_on_course("main", np.array([10.0, 0, 0]), v, 2.0, radius),)
    )


def scenario2() -> Encounter:
    """Climbing at 20°: main threat R = 1 from below, v = (0, -2, 2), at p_c = 10·d̂ at τ = 2 s;
    two R = 1 threats flying along the reference at 5 m/s, 2 m ahead and ±3.5 m to the sides."""
    g = np.radians(20.0)
    d = np.array([np.cos(g), 0.0, np.sin(g)])
    main = _on_course("main", 10.0 * d, np.array([0.0, -2.0, 2.0]), 2.0, 1.0)
    side = tuple(Threat(f"parallel_{s:+.0f}", np.array([0.0, s, 0.0]) + 2.0 * d, SPEED * d, 1.0) for s in (3.5, -3.5))
    return Encounter(np.zeros(3), d, (main, *side))


def scenario3(moving_main: bool, diagonal_shift_m: float = 0.0) -> Encounter:
    """Main threat R = 2 at p_c = (10, 0, 0) (static, or climbing at 3 m/s to reach p_c at τ = 2 s)
    and two R = 1 threats moving diagonally above the collision point, both moved sideways by
    ``diagonal_shift_m`` [m] (+y, left).

    With no shift (the spec's reconstruction) the scene is symmetric under the half turn about
    the vertical through p_c: a left path and its right mirror have equal time-free cost terms, so
    the side of a lateral path is a tie (decided by rounding). The thesis reports "left" but gives
    no coordinates; with the diagonal threats shifted right (< 0) left is the cheaper side."""
    p_c = np.array([10.0, 0.0, 0.0])
    main = (
        _on_course("main", p_c, np.array([0.0, 0.0, 3.0]), 2.0, 2.0)
        if moving_main
        else Threat("main", p_c, np.zeros(3), 2.0)
    )
    shift = np.array([0.0, diagonal_shift_m, 0.0])
    return Encounter(
        np.zeros(3),
        np.array([1.0, 0.0, 0.0]),
        (
            main,
            Threat("diag_a", np.array([6.0, -6.0, 4.0]) + shift, np.array([1.5, 1.5, 0.0]), 1.0),
            Threat("diag_b", np.array([14.0, 6.0, 4.0]) + shift, np.array([-1.5, -1.5, 0.0]), 1.0),
        ),
    )
