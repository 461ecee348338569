"""Rule engine (spec §7.6): rules attached to the decision points of the mission-control run,
configured per UAS by an enabled-rules table.

A rule has a ``code``, an optional decision ``point`` (rules without one are only invoked by
other rules, e.g. the manoeuvre rules by *resolve*), a ``priority`` (lower first), a
``condition`` and an ``apply``; both read and write the shared :class:`RuleContext`. Every
applied rule is recorded (``ctx.decisions``) and turned into events of the decision frame.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import Enum
from typing import TYPE_CHECKING, Protocol

import numpy as np

from avoidance.utm.cases import CaseBook
from avoidance.utm.collision_case import CollisionCase
from avoidance.utm.directives import UtmInbox
from avoidance.utm.notification import PositionNotification
from avoidance.utm.response import PeerTalk
from avoidance.utm.weather_case import WeatherCase

if TYPE_CHECKING:
    from avoidance.reachset.frames import GridPose
    from avoidance.reachset.gridrun import GridRun
    from avoidance.reachset.mission import Decision
    from avoidance.reachset.tree import ReachSetTree
    from avoidance.rules.config import RulesConfig


class DecisionPoint(str, Enum):
    BEFORE_AVOIDANCE_RUN = "before_avoidance_run"  # before step 7: cases in, modes
    TRAJECTORY_RESTRICTIONS = "trajectory_restrictions"  # navigation run, before path selection
    AFTER_AVOIDANCE_RUN = "after_avoidance_run"  # after step 11: closing, reports


@dataclass(slots=True)
class RuleContext:
    """What the rules of one decision frame see and change. Frames: GCF (ENU) [m], sim s."""

    uas: str
    t: float
    cfg: RulesConfig
    book: CaseBook
    notifications: list[PositionNotification]
    length: float  # movement length at cruise [m]
    frame: float  # decision frame = movement period [s]
    start: float = 0.0  # time of the UAS' first decision [s]
    resolve: list[CollisionCase] = field(default_factory=list)  # own cases to resolve, by severity
    emergency: set[str] = field(default_factory=set)  # peers handed to the emergency avoidance
    managed: set[str] = field(default_factory=set)  # peers whose pair with the own UAS was assessed
    unresolved: set = field(default_factory=set)  # (ids, head time) of chains reported unresolved (carried over)
    events: list[str] = field(default_factory=list)
    decisions: list[dict] = field(default_factory=list)
    decision: Decision | None = None
    run: GridRun | None = None
    disabled: np.ndarray | None = None  # nodes disabled so far (navigation reach set)
    goal_override: np.ndarray | None = None  # GCF waypoint flown instead of the mission goal
    path_found: bool | None = None  # the restricted navigation run found a path
    deadlock_frames: int = 0  # consecutive frames without a restricted path (carried over)
    held: bool = False  # this frame's soft deadlock is waited out hovering (the planner's hold)
    case: CollisionCase | None = None  # the case a manoeuvre / restriction rule works on
    margin: float = 0.0  # the margin [m] the safety-margin rule enforces for ``case``
    speed: float | None = None  # the speed [m/s] the rules command this frame (6.202), None: cruise
    weather: list[WeatherCase] = field(default_factory=list)  # this frame's weather cases
    goal: np.ndarray | None = None  # GCF [m] the run flies to (mission goal or the rules' override)
    utm: UtmInbox | None = None  # the central UTM's directives (None: virtual UTM only)
    peers: PeerTalk | None = None  # the vehicle-to-vehicle link (None: none)

    @property
    def unit(self) -> float:
        """The scale of the thesis' metre [m] (config)."""
        return self.cfg.unit

    def note(self, uas: str) -> PositionNotification | None:
        """This frame's notification of ``uas`` (the own one under :attr:`uas`), None if none."""
        return next((n for n in self.notifications if n.id == uas), None)

    def own_note(self) -> PositionNotification:
        """This frame's own notification (always present)."""
        own = self.note(self.uas)
        if own is None:
            raise RuntimeError("the frame has no own notification")
        return own

    def peer_note(self, case: CollisionCase) -> PositionNotification:
        """This frame's notification of the case's other UAS (a case's peer is always notified)."""
        peer = self.note(case.other(self.uas))
        if peer is None:
            raise RuntimeError(f"no notification of {case.other(self.uas)}")
        return peer

    def current_case(self) -> CollisionCase:
        """The case the running manoeuvre / restriction rule works on."""
        if self.case is None:
            raise RuntimeError("no collision case is selected")
        return self.case

    def current_decision(self) -> Decision:
        """This frame's mission-control decision."""
        if self.decision is None:
            raise RuntimeError("the frame has no decision yet")
        return self.decision

    def current_run(self) -> GridRun:
        """This frame's navigation run."""
        if self.run is None:
            raise RuntimeError("the frame has no navigation run yet")
        return self.run

    def navigation_tree(self) -> tuple[ReachSetTree, GridPose]:
        """The reach-set tree of this frame's decision and the grid's pose (the restriction masks'
        inputs)."""
        d = self.current_decision()
        if d.tree is None:
            raise RuntimeError("the frame's decision has no reach-set tree")
        return d.tree, d.pose

    def record(self, rule: str, case: CollisionCase | None = None, **info) -> None:
        """One rule decision: an event ``rule:<code>[:<own>-<peer>:<encounter>:<own role>]`` and a
        record."""
        tag = f"rule:{rule}"
        if case is not None:
            tag += f":{self.uas}-{case.other(self.uas)}:{case.encounter.value}:{case.role_of(self.uas).value}"
        self.events.append(tag)
        self.decisions.append({"rule": rule, **({"case": case.record()} if case is not None else {}), **info})

    def disable(self, rule: str, mask: np.ndarray, case: CollisionCase) -> None:
        n = int(mask.sum()) if self.disabled is None else int((mask & ~self.disabled).sum())
        self.disabled = mask.copy() if self.disabled is None else self.disabled | mask
        self.record(rule, case, disabled_nodes=n)


class Rule(Protocol):
    code: str
    point: DecisionPoint | None
    priority: int

    def condition(self, ctx: RuleContext) -> bool: ...

    def apply(self, ctx: RuleContext, engine: RuleEngine) -> None: ...


class RuleEngine:
    """Enabled rules by decision point, in priority order; ``enabled(code)`` for rules that
    other rules invoke."""

    def __init__(self, rules: Sequence[Rule]):
        self.rules = {r.code: r for r in rules}
        self.table: dict[DecisionPoint, list[Rule]] = {
            p: sorted((r for r in rules if r.point == p), key=lambda r: r.priority) for p in DecisionPoint
        }

    def enabled(self, code: str) -> bool:
        return code in self.rules

    def call(self, code: str, ctx: RuleContext) -> bool:
        """Invoke the enabled rule ``code`` if its condition holds; whether it was applied."""
        rule = self.rules.get(code)
        if rule is None or not rule.condition(ctx):
            return False
        rule.apply(ctx, self)
        return True

    def invoke(self, point: DecisionPoint, ctx: RuleContext) -> None:
        for rule in self.table[point]:
            if rule.condition(ctx):
                rule.apply(ctx, self)
