"""Configuration of one UAS' rules of the air (options of a ``reachset`` planner: ``rules`` =
the enabled-rules table, ``rules_<field>`` = the other fields): registration, margins, UTM.

Units: margins and bloat in multiples of ``unit`` [m], the scale of the thesis' metre (its
numbers are for 1 m movements at 1 m/s; every UAS of one scenario must use the same ``unit``
so that they file the same margins, docs/rules.md); the UTM time margin in grid ranges flown at
cruise speed; heights [m].
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

from avoidance.reachset.config import AvoidanceConfig, ExpansionConfig, ReachSetConfig
from avoidance.utm.collision_case import UtmConfig
from avoidance.utm.notification import Category, Maneuverability, Margins, Registration

RULE_CODES = (
    "detect",
    "resolve",
    "close",
    "head_on",
    "converging",
    "overtake",
    "right_plane_heading",
    "safety_margin",
    "weather",
)


@dataclass(frozen=True, slots=True)
class RulesConfig:
    """``enabled``: rule codes (default all of :data:`RULE_CODES`); ``unit`` [m]; margins [unit]
    ([R] defaults universal 5, head-on 5, converging 8, overtake 5); ``converging_extra`` [unit]
    added to the give-way UAS' ball ([R] adds 4; default 0: the ball around the right-of-way
    UAS' own predicted track does that job, and with 4 more the give-way UAS detected at 20
    units from the point has no trajectory left, docs/rules.md); ``bloat`` [unit] added to every enforced margin
    (synchronisation bloat 6.180: peer speed × decision frame = 1 thesis metre);
    ``established_speed`` share of the cruise speed and ``settle`` [s] after its first decision
    from which the own UAS takes part in cases (start transients of the estimator and the
    controller make early headings meaningless, and the head case fixes the roles);
    ``deadlock_frames`` frames in a row without a restricted navigation path before the peers go
    to the emergency avoidance; ``plane_tolerance`` [unit] how far left of the right-plane a
    trajectory may reach (the plane moves with the estimates: without slack every frame whose
    heading is a little left of the line to the collision point disables all turns,
    docs/rules.md); ``plane_horizon`` [s] the turning time horizon of the right plane's linear
    projection from every movement end (6.217; 0 = only the trajectory's own points, 6.216);
    ``hold``: a multirotor giving way to peers that hold course may hover out a soft deadlock
    (R-18, :meth:`avoidance.rules.planner.RulesAvoider._hold`);
    ``time_margin`` [grid ranges at cruise] how far ahead a closest approach
    opens a case; ``weather_margin`` [unit] the soft band around a weather case's body (§7.5);
    ``airspace`` ``uncontrolled`` (ball, 6.218)
    or ``controlled`` (well-clear barrel of half height ``barrel_half_height`` [m], 6.219);
    ``navigation``: the planar separations of the ACAS-like navigation reach set the rules
    restrict (the [R] cooperative scenarios S9-S13 use ``horizontal``: a right-plane heading
    then means a turn to the right, not a climb or descent on the plane), ``navigation_spread``
    its spread limit per cell (unlimited keeps so many equal-cost paths that the first movement
    of the chosen one is mostly Straight: replanned every frame, the turn to a goal far off the
    heading is postponed for ever; 9 as the harmonic default turns first, docs/rules.md);
    ``filed``: registrations the UTM holds for peers that differ from the own one, peer id ->
    ``{"category": ..., "maneuverability": ...}`` (e.g. a HAPS, ``linear_propulsion``, among
    multirotors: it gets the right of way); a peer not listed files the own registration;
    ``plans``: mission plans the UTM holds for peers (intent sharing), peer id -> horizontal
    waypoints ``[[north, east], ...]`` [m] from the scenario origin, flown at the peer's current
    altitude: such a peer is predicted along its plan's remaining legs (a waypoint counts as
    reached once the peer's track comes within two movement lengths of it), not linearly."""

    enabled: tuple[str, ...] = RULE_CODES
    unit: float = 1.0
    universal: float = 5.0
    head_on: float = 5.0
    converging: float = 8.0
    overtake: float = 5.0
    converging_extra: float = 0.0
    plane_tolerance: float = 1.0
    plane_horizon: float = 0.0
    widest: bool = True
    hold: bool = True
    bloat: float = 1.0
    time_margin: float = 2.0
    weather_margin: float = 5.0
    airspace: str = "uncontrolled"
    barrel_half_height: float = 76.2
    category: str = "uas_autonomous"
    maneuverability: str = "vtol"
    close_after: int = 2
    established_speed: float = 0.8
    settle: float = 0.0
    deadlock_frames: int = 3
    navigation: tuple[str, ...] = ("horizontal",)
    navigation_spread: int = 9
    filed: dict[str, dict[str, str]] = field(default_factory=dict)
    plans: dict[str, list[list[float]]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        unknown = sorted(set(self.enabled) - set(RULE_CODES))
        if unknown:
            raise ValueError(f"unknown rule(s) {', '.join(unknown)} (known: {', '.join(RULE_CODES)})")
        if self.airspace not in ("uncontrolled", "controlled"):
            raise ValueError(f"airspace must be 'uncontrolled' or 'controlled', not {self.airspace!r}")
        _check_class(self.category, self.maneuverability)
        for peer, reg in self.filed.items():
            if not isinstance(reg, dict) or set(reg) - {"category", "maneuverability"}:
                raise ValueError(f"filed.{peer}: a table of category and/or maneuverability, not {reg!r}")
            _check_class(reg.get("category", self.category), reg.get("maneuverability", self.maneuverability))
        for peer, plan in self.plans.items():
            if not (
                isinstance(plan, list | tuple)
                and plan
                and all(isinstance(w, list | tuple) and len(w) == 2 for w in plan)
            ):
                raise ValueError(f"plans.{peer}: a list of [north, east] waypoints [m], not {plan!r}")
        bad = sorted(set(self.navigation) - {"horizontal", "vertical", "slash", "backslash"})
        if bad or not self.navigation:
            raise ValueError(
                f"navigation: unknown separation(s) {', '.join(bad) or '(none given)'} "
                "(known: horizontal, vertical, slash, backslash)"
            )
        if not (isinstance(self.navigation_spread, int) and self.navigation_spread >= 1):
            raise ValueError("navigation_spread must be an integer >= 1")
        if not self.unit > 0.0:
            raise ValueError("unit must be > 0")
        for name in (
            "universal",
            "head_on",
            "converging",
            "overtake",
            "converging_extra",
            "bloat",
            "time_margin",
            "weather_margin",
            "plane_tolerance",
            "plane_horizon",
            "established_speed",
            "settle",
        ):
            if not getattr(self, name) >= 0.0:
                raise ValueError(f"{name} must be >= 0")

    @staticmethod
    def from_options(options: dict) -> RulesConfig:
        """From a scenario's options (lists for the tuples); ValueError naming the field."""
        known = {f.name for f in fields(RulesConfig)}
        unknown = sorted(set(options) - known)
        if unknown:
            raise ValueError(f"rules: unknown option(s) {', '.join(unknown)} (known: {', '.join(sorted(known))})")
        opts = dict(options)
        for name in ("enabled", "navigation"):
            if name in opts:
                opts[name] = tuple(opts[name])
        try:
            return RulesConfig(**opts)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"rules: {exc}") from None

    def registration(self, uas: str, cruise: float) -> Registration:
        """The registration filed for ``uas`` (margins in metres)."""
        reg = self.filed.get(uas, {})
        category, maneuverability = reg.get("category", self.category), reg.get("maneuverability", self.maneuverability)
        return Registration(
            uas,
            Category[category.upper()],
            Maneuverability[maneuverability.upper()],
            Margins(self.universal, self.head_on, self.converging, self.overtake, self.weather_margin).scaled(
                self.unit
            ),
            min_cruise=0.5 * cruise,
            max_cruise=cruise,
        )

    def avoidance(self, base: AvoidanceConfig = AvoidanceConfig()) -> AvoidanceConfig:
        """The reach-set configuration flown under these rules (navigation reach set replaced)."""
        return replace(
            base, navigation=ReachSetConfig.single(ExpansionConfig.acas(self.navigation, self.navigation_spread))
        )

    def utm(self, grid_range: float, cruise: float) -> UtmConfig:
        thesis = UtmConfig()  # speeds in thesis m/s, scaled like the lengths (1 s movement period)
        return UtmConfig(
            time_margin=self.time_margin * grid_range / max(cruise, 1e-6),
            speed_tolerance=thesis.speed_tolerance * self.unit,
            close_after=self.close_after,
            min_speed=0.2 * cruise,
            angle_doubt=thesis.angle_doubt,
            speed_doubt=thesis.speed_doubt * self.unit,
        )


def _check_class(category: str, maneuverability: str) -> None:
    if category.upper() not in Category.__members__:
        raise ValueError(f"unknown category {category!r} (known: {', '.join(m.lower() for m in Category.__members__)})")
    if maneuverability.upper() not in Maneuverability.__members__:
        raise ValueError(
            f"unknown maneuverability {maneuverability!r} "
            f"(known: {', '.join(m.lower() for m in Maneuverability.__members__)})"
        )


RULES_FIELDS = tuple(f.name for f in fields(RulesConfig) if f.name != "enabled")
