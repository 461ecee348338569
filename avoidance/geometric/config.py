"""Configuration of the geometric avoider (spec avoidance-geometric.md §2.8, §5, §9.2).

Frozen dataclasses, validated on construction so that a bad value fails where it is set.
Units: SI (m, s, kg, W, J); angles are not configured here (plane angles follow from ``n_planes``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

PATH_TYPES = ("simple", "symmetric")
DYNAMIC_MODES = ("timed", "swept")
UAV_SHAPES = ("sphere_inscribed", "sphere_circumscribed")
SMOOTHNESS_METHODS = ("curvature", "std", "second_derivative")


def _require(cond: bool, msg: str) -> None:
    if not cond:
        raise ValueError(msg)


def _positive(name: str, value: float) -> None:
    _require(math.isfinite(value) and value > 0, f"{name} must be finite and > 0, got {value!r}")


@dataclass(frozen=True, slots=True)
class VehicleParams:
    """Multirotor constants (thesis Table 1.1, Tarot quad) and performance limits.

    ``v_cruise`` [m/s] is the speed on every path segment, ``max_roc`` [m/s] caps |v_z| in climb
    and descent. Blade constants feed the hover-power diagnostic only (spec §5.6, G19)."""

    mass: float = 3.0
    drag_coefficient: float = 0.5
    effective_area: float = 2.5
    blades_per_rotor: int = 2
    blade_chord: float = 0.035
    blade_radius: float = 0.1905
    n_rotors: int = 4
    v_cruise: float = 5.0
    max_roc: float = 3.0
    blade_cd: float = 0.01
    v_tip: float = 0.8 * 340.29
    k_induced: float = 1.15

    def __post_init__(self) -> None:
        for name in (
            "mass",
            "drag_coefficient",
            "effective_area",
            "blade_chord",
            "blade_radius",
            "v_cruise",
            "max_roc",
            "blade_cd",
            "v_tip",
            "k_induced",
        ):
            _positive(name, getattr(self, name))
        _require(self.blades_per_rotor >= 1 and self.n_rotors >= 1, "blade and rotor counts must be >= 1")


@dataclass(frozen=True, slots=True)
class CostCaps:
    """Clip/min-max limits of the time [s] and energy [J] terms (spec §5.7); ``time_hi`` already
    includes the x1.15 factor. Defaults: our own sweep for the default vehicle and config
    (``scripts/geometric_caps_sweep.py``, derivation in docs/geometric.md)."""

    time_lo: float = 1.6487
    time_hi: float = 8.2326
    energy_lo: float = 312.60
    energy_hi: float = 1434.64

    def __post_init__(self) -> None:
        for name in ("time_lo", "time_hi", "energy_lo", "energy_hi"):
            _require(math.isfinite(getattr(self, name)), f"{name} must be finite")
        _require(0 <= self.time_lo < self.time_hi, "need 0 <= time_lo < time_hi")
        _require(0 <= self.energy_lo < self.energy_hi, "need 0 <= energy_lo < energy_hi")


@dataclass(frozen=True, slots=True)
class GeometricConfig:
    """Planner settings. Defaults are the operational choice of issue 7: both path types,
    time-synchronised moving-threat check. ``GeometricConfig.thesis()`` gives the thesis setup
    (conservative swept check, no latency shift, no covariance inflation).

    - ``l``: ω-grid density (l+1 offsets in [-3.2R, 3.2R], |ω| <= R dropped); ``n_planes``: extra
      planes at 180°·i/(n+1).
    - ``x_step_fraction``: sample step along the shape as a fraction of Δx (16 / 21 points).
    - ``collision_radius`` [m]: side of the UAV box; ``uav_shape`` picks the inscribed (side/2)
      or circumscribed (side·√3/2) sphere for the analytic check.
    - ``dynamic_mode``: ``timed`` compares UAV and threat at the same time (over the candidate and
      the reference after the rejoin, up to the longest candidate + ``rejoin_check_s``);
      ``swept`` rejects a candidate near any point of a threat's collision path (thesis).
    - ``select_margin_m`` [m]: extra clearance a candidate needs to be chosen (and a predicted
      miss needs to count as a conflict); the committed path's re-check uses ``r_uav`` alone, so
      the margin is also a hysteresis against track noise (closed loop; 0 = thesis).
    - ``main_threat_extension_s`` [s]: swept mode, extends a moving main threat past p_c.
    - ``k_sigma``: threat radius inflation in standard deviations of the track covariance.
    - ``k_sigma_own``: threat radius inflation in standard deviations of the ownship's own
      position estimate (its largest axis, ``VehicleState.pos_sigma_m``; nothing when the estimate
      carries none): the relative position is wrong by the ownship's error as much as by the
      track's, and a candidate's clearance is judged from the estimate (0 = the spec's avoider).
    - ``start_shift_s`` [s]: latency compensation, start point moved ahead along the reference.
    - ``weights``: (k_S, k_T, k_C) on normalised S_rp, T and CMO.
    - ``log_limits``: ln-space clip limits of (S, S_rp, M).
    - ``max_cost``: optional threshold above which the result is NO_SOLUTION.
    - ``min_height_m`` [m]: optional floor, the lowest height above the local origin (ENU z) a
      candidate may reach; candidates dipping below it are not available (None: no floor, the
      spec's avoider knows no ground).
    - ``conflict_horizon_s`` [s]: look-ahead of the constant-velocity conflict monitor.
    - ``min_replan_interval_s`` [s]: least time between two candidate generations in the closed
      loop (spec §9.6); a conflict inside it gets the no-candidate fallback (hover, or fly on).
    - ``replan_max_offset_m`` [m]: a committed path found unsafe is dropped for a re-plan only
      while the vehicle is within this distance of the reference; farther off, it hovers and
      resumes the path when it is clear again.
    """

    l: int = 4  # noqa: E741 (the spec's symbol l, and the scenario key)
    n_planes: int = 3
    omega_factor: float = 3.2
    path_types: tuple[str, ...] = ("simple", "symmetric")
    min_sep_factor: float = 2.5
    x_step_fraction: float = 0.1
    collision_radius: float = 2.0
    uav_shape: str = "sphere_inscribed"
    dynamic_mode: str = "timed"
    rejoin_check_s: float = 2.0
    select_margin_m: float = 0.0
    main_threat_extension_s: float = 0.0
    k_sigma: float = 0.0
    k_sigma_own: float = 0.0
    smoothness: str = "curvature"
    k_p: float = 1.0
    k1: float = 0.5
    k2: float = 0.5
    weights: tuple[float, float, float] = (0.30, 0.20, 0.50)
    log_limits: tuple[tuple[float, float], ...] = ((-3.0, 2.5), (-3.0, 3.0), (-3.0, 0.001))
    cmo_max_objects: int = 3
    cmo_max_range_m: float = math.inf
    cmo_threat_samples: int = 50
    cmo_min_distance: float = 0.05
    start_shift_s: float = 0.75
    max_cost: float | None = None
    min_height_m: float | None = None
    conflict_horizon_s: float = 10.0
    min_replan_interval_s: float = 0.5
    replan_max_offset_m: float = 2.0
    rho: float = 1.225
    g: float = 9.81
    hover_literal_ki: bool = False
    caps: CostCaps = field(default_factory=CostCaps)

    def __post_init__(self) -> None:
        _require(self.l >= 1 and self.n_planes >= 0, "need l >= 1 and n_planes >= 0")
        _require(
            len(self.path_types) >= 1
            and set(self.path_types) <= set(PATH_TYPES)
            and len(set(self.path_types)) == len(self.path_types),
            f"path_types must be distinct values of {PATH_TYPES}, got {self.path_types!r}",
        )
        _require(self.dynamic_mode in DYNAMIC_MODES, f"dynamic_mode must be one of {DYNAMIC_MODES}")
        _require(self.uav_shape in UAV_SHAPES, f"uav_shape must be one of {UAV_SHAPES}")
        _require(self.smoothness in SMOOTHNESS_METHODS, f"smoothness must be one of {SMOOTHNESS_METHODS}")
        _require(self.omega_factor > 1.0, "omega_factor must be > 1 (offsets |ω| <= R are dropped)")
        _require(0 < self.x_step_fraction <= 0.5, "x_step_fraction must be in (0, 0.5]")
        for name in ("min_sep_factor", "collision_radius", "rho", "g", "cmo_min_distance"):
            _positive(name, getattr(self, name))
        for name in (
            "rejoin_check_s",
            "select_margin_m",
            "main_threat_extension_s",
            "k_sigma",
            "k_sigma_own",
            "k_p",
            "start_shift_s",
            "k1",
            "k2",
            "min_replan_interval_s",
            "replan_max_offset_m",
        ):
            v = getattr(self, name)
            _require(math.isfinite(v) and v >= 0, f"{name} must be finite and >= 0, got {v!r}")
        _positive("conflict_horizon_s", self.conflict_horizon_s)
        _require(
            self.min_height_m is None or math.isfinite(self.min_height_m),
            f"min_height_m must be finite or None, got {self.min_height_m!r}",
        )
        _require(self.cmo_max_range_m > 0, "cmo_max_range_m must be > 0")
        _require(
            self.cmo_max_objects >= 1 and self.cmo_threat_samples >= 2,
            "need cmo_max_objects >= 1 and cmo_threat_samples >= 2",
        )
        _require(
            len(self.weights) == 3 and all(w >= 0 for w in self.weights) and abs(sum(self.weights) - 1.0) < 1e-9,
            "weights must be 3 values >= 0 summing to 1",
        )
        _require(
            len(self.log_limits) == 3 and all(lo < hi for lo, hi in self.log_limits),
            "log_limits must be 3 (lo, hi) pairs with lo < hi",
        )

    @classmethod
    def thesis(cls, **overrides) -> GeometricConfig:
        """The thesis configuration: swept moving-threat check, no latency shift, k_σ = 0."""
        return cls(**{"dynamic_mode": "swept", "start_shift_s": 0.0, "k_sigma": 0.0, **overrides})

    @property
    def r_uav(self) -> float:
        """Radius [m] of the sphere standing for the UAV box in the analytic check (G10)."""
        half = 0.5 * self.collision_radius
        return half if self.uav_shape == "sphere_inscribed" else half * math.sqrt(3.0)
