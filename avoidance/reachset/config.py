"""Configuration of the reach-set avoidance (spec avoidance-reach-set.md), as frozen dataclasses.

Units: metres, seconds, radians (degrees only in files meant for people). Every number of the
method lives here; the defaults are the thesis values ([T]) or the spec's decisions ([D]).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from math import pi


@dataclass(frozen=True, slots=True)
class MovementConfig:
    """One movement set (spec §2.3/§2.5): constant speed ``speed`` [m/s] for ``period`` [s] while
    pitch and yaw change at constant rate by at most ``dpitch`` / ``dyaw`` [rad] per movement.
    ``n_sub`` intra-movement samples are used for passing cells and entry/leave times (§2.4)."""

    speed: float = 1.0
    period: float = 1.0
    dpitch: float = pi / 12
    dyaw: float = pi / 12
    n_sub: int = 10

    @property
    def length(self) -> float:
        """Nominal movement length L = v T [m]."""
        return self.speed * self.period


@dataclass(frozen=True, slots=True)
class GridConfig:
    """Polar Avoidance Grid in the local frame (spec §3.2/§3.3): distance, horizontal angle θ
    (left positive) and elevation φ (up positive) ranges, cell counts per axis, boundary epsilon."""

    d_range: tuple[float, float] = (0.0, 10.0)
    theta_range: tuple[float, float] = (-pi / 4, pi / 4)
    phi_range: tuple[float, float] = (-pi / 6, pi / 6)
    n_layers: int = 10
    n_h: int = 7
    n_v: int = 5
    eps: float = 1e-9
    safe_layers: int = 3  # zones of §3.7: safe = 1..3, crash = last 3
    crash_layers: int = 3
    samples_per_axis: int = 4  # volume samples per cell and axis (map obstacles, constraints)

    def scaled(self, length: float) -> GridConfig:
        """The same grid for a movement length ``length`` [m] (range = layers × L, §2.7)."""
        d0, d1 = self.d_range
        return GridConfig(
            (d0 * length, d1 * length),
            self.theta_range,
            self.phi_range,
            self.n_layers,
            self.n_h,
            self.n_v,
            self.eps,
            self.safe_layers,
            self.crash_layers,
            self.samples_per_axis,
        )


@dataclass(frozen=True, slots=True)
class ExpansionConfig:
    """Expansion constraint of the wave-front (spec §4.5-4.8). ``method`` is ``chaotic``
    (side-wall metric, key = last ``footprint_length`` cells), ``harmonic`` (centre metric over
    smoothness, key = whole footprint) or ``acas`` (harmonic metric, buffers restricted to the
    planar ``separations``). ``spread_limit`` None = unlimited. ``attitude_key`` adds the tip
    attitude (pitch, yaw in movement increments) to the dedupe key (decision D-1 of docs/reachset.md:
    without it the harmonic set collapses to one trajectory per cell-centre ray)."""

    method: str = "chaotic"
    spread_limit: int | None = 9
    footprint_length: int | None = 3
    separations: tuple[str, ...] = ("horizontal",)
    prune_to_final_layer: bool = True
    prune_last_spread: bool = True
    max_extra_depth: int = 3
    attitude_key: bool = True

    @staticmethod
    def chaotic(spread: int | None = 9, footprint_length: int | None = 3, **kw) -> ExpansionConfig:
        return ExpansionConfig("chaotic", spread, footprint_length, **kw)

    @staticmethod
    def harmonic(spread: int | None = 9, **kw) -> ExpansionConfig:
        return ExpansionConfig("harmonic", spread, None, **kw)

    @staticmethod
    def acas(separations: tuple[str, ...] = ("horizontal",), spread: int | None = None, **kw) -> ExpansionConfig:
        return ExpansionConfig("acas", spread, None, separations, **kw)


@dataclass(frozen=True, slots=True)
class ReachSetConfig:
    """A reach set = one expansion, or the union (``combined``, alg. 6.4) of several. ``cost_mode_switch``
    multiplies the base cost by (2 - smoothness) (6.84); ``pitch_cost`` is the per-movement
    factor of a pitching movement in the base cost (A-10)."""

    parts: tuple[ExpansionConfig, ...] = (ExpansionConfig.chaotic(),)
    cost_mode_switch: bool = False
    pitch_cost: float = 1.2

    @staticmethod
    def combined(chaotic_spread: int = 8, footprint_length: int = 3, harmonic_spread: int = 1) -> ReachSetConfig:
        return ReachSetConfig(
            (ExpansionConfig.chaotic(chaotic_spread, footprint_length), ExpansionConfig.harmonic(harmonic_spread)),
            cost_mode_switch=True,
        )

    @staticmethod
    def single(part: ExpansionConfig) -> ReachSetConfig:
        return ReachSetConfig((part,))


@dataclass(frozen=True, slots=True)
class LidarConfig:
    """LiDAR rating (spec §5.1): minimal scanned surface that counts as a full obstacle [m²]."""

    threshold_area: float = 0.25


@dataclass(frozen=True, slots=True)
class MapConfig:
    """Map obstacles (spec §5.2): safety margin around each body [m], threshold volume [m³]
    (a cell whose volume inside the obstacle reaches it rates 1)."""

    safety_margin: float = 0.5
    threshold_volume: float = 0.01


@dataclass(frozen=True, slots=True)
class ConstraintConfig:
    """Static/moving constraints (spec §5.3/§5.5): margin ring width [m] (soft), ``mode`` =
    ``polygon`` (exact, shapely) or ``circle`` (Welzl barrel of the thesis)."""

    safety_margin: float = 5.0
    mode: str = "polygon"


@dataclass(frozen=True, slots=True)
class IntruderModelConfig:
    """Intruder space/time models (spec §5.4). Flags select line/body/spread (cone) models and
    the time-intersection rate; ``theta_i``/``phi_i`` are the manoeuvre-uncertainty half angles
    [rad]; ``path_step`` the spacing of the line/body centre samples along the predicted path, in
    layer depths of the grid (the body is grown by half of it, so the sampled balls cover the swept
    body); ``spacing`` the cone's lattice spacing [m]; ``time_error`` widens the UAS window [s];
    ``cone_steps`` lattice points per ellipse axis; ``density`` ``mean`` (6.133) or ``product``;
    ``body_margin`` [m] is added to every intruder's body radius (safety-margin bloat, §8.2);
    ``vertical_margin`` [m] stretches every body vertically into a capsule (the centre anywhere
    within ± this of its predicted height): the allowance for the ownship's vertical navigation
    error, which the estimate does not carry (docs/encounters.md finding 11);
    ``give_way_turn_rate`` [rad/s]: every intruder is also predicted turning right at this rate,
    as the rules of the air have aircraft give way, in the intruder space and in the last
    resort's clearance, and the last resort turns right (D-21; 0 = straight lines only, D-18;
    default the thesis' 15° per 1 s movement)."""

    line: bool = True
    body: bool = True
    spread: bool = False
    timed: bool = True
    theta_i: float = pi / 8
    phi_i: float = pi / 12
    path_step: float = 0.1
    spacing: float = 0.2
    time_error: float = 1.0
    cone_steps: int = 7
    density: str = "mean"
    body_margin: float = 0.0
    vertical_margin: float = 0.0
    give_way_turn_rate: float = pi / 12

    @staticmethod
    def cooperative(**kw) -> IntruderModelConfig:
        return IntruderModelConfig(line=True, body=True, spread=False, timed=True, **kw)

    @staticmethod
    def non_cooperative(**kw) -> IntruderModelConfig:
        return IntruderModelConfig(line=True, body=False, spread=True, timed=False, **kw)


@dataclass(frozen=True, slots=True)
class FusionConfig:
    """Data fusion thresholds (tab. 6.5): 1e-7 ([T]) or 0.02 (``reference_impl``, A-16)."""

    threshold: float = 1e-7


@dataclass(frozen=True, slots=True)
class MissionConfig:
    """Mission control (spec §6.2): waypoint-reached radius in movement lengths (def. 20),
    replanning policy ``every_frame`` or ``event_driven`` (steps 5/13); ``stop_and_wait``: a
    vehicle that hovers and turns in place may, in emergency mode, stop at the grid origin for a
    movement period and then fly from there facing the goal (D-23)."""

    reach_radius_lengths: float = 2.0
    replan_policy: str = "every_frame"
    stop_and_wait: bool = False


@dataclass(frozen=True, slots=True)
class AvoidanceConfig:
    """Everything one vehicle's reach-set avoidance needs."""

    grid: GridConfig = field(default_factory=GridConfig)
    navigation: ReachSetConfig = field(default_factory=lambda: ReachSetConfig.single(ExpansionConfig.harmonic()))
    avoidance: ReachSetConfig = field(default_factory=ReachSetConfig.combined)
    lidar: LidarConfig = field(default_factory=LidarConfig)
    map: MapConfig = field(default_factory=MapConfig)
    constraints: ConstraintConfig = field(default_factory=ConstraintConfig)
    intruders: IntruderModelConfig = field(default_factory=IntruderModelConfig.cooperative)
    fusion: FusionConfig = field(default_factory=FusionConfig)
    mission: MissionConfig = field(default_factory=MissionConfig)


DEFAULT_AVOIDANCE = AvoidanceConfig()  # shared default of the planners (frozen)
