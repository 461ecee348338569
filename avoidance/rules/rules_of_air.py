"""The rules of the air (spec §7.7): detect, resolve and close collision cases; the manoeuvre
rules head-on, converging and overtake; the restrictions right-plane heading and enforce safety
margin. Frames: GCF (ENU) [m] for cases and waypoints; the navigation reach set in the LCF of
the decision's grid. Margins here are metres (the config's lengths times L).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import shapely

from avoidance.rules.engine import DecisionPoint, RuleContext, RuleEngine
from avoidance.rules.restrictions import (
    moving_margin_mask,
    path_clearance,
    right_plane_heading_mask,
    safety_margin_mask,
    weather_masks,
    widest_per_cell,
)
from avoidance.rules.utm_merge import merge_utm
from avoidance.utm.cases import as_roundabout
from avoidance.utm.collision_case import CollisionCase, Encounter, Role, closest_approach

SEVERITY = {Encounter.HEAD_ON: 0, Encounter.CONVERGING: 1, Encounter.OVERTAKE: 2}
ROUNDABOUT_LEAD_RAD = 0.5  # a chord of 0.5 rad keeps 97 % of the roundabout radius from the centre
RESOLVING = {Role.ROUNDABOUT: "head_on", Role.CONVERGING: "converging", Role.OVERTAKING: "overtake"}


def overtake_speed(min_cruise: float, intruder_speeds) -> float:
    """(6.202) Speed when several overtakes meet: ``max(minCruise, min intruder speed)`` [m/s]."""
    return max(min_cruise, min(intruder_speeds))


def overtake_waypoints(
    p_uas, v_uas, p_overtaken, v_overtaken, cp, margin: float, frame: float, reach_margin: float
) -> tuple[np.ndarray, np.ndarray]:
    """Divergence and convergence waypoints (6.207-6.214, 6.209 with its square), GCF [m]:
    in the overtaken UAS' frame (X+ along its velocity, Y+ left, origin at the collision point
    moved horizontally onto the overtaken UAS' track) divergence = (0, -(Δv·frame + margin)),
    convergence = (safeOffset, same), with safeOffset = sqrt(|p_uas - cp|² + margin²) + Δv·frame
    + reach_margin. The collision point is the midpoint of both UAS at the closest approach
    (6.189), off the overtaken track by half the miss distance; the lateral offset is measured
    from the track, so that the waypoints keep ``margin`` + Δv·frame from the overtaken UAS
    (6.206) whichever side the overtaking UAS came from."""
    p_uas, cp = np.asarray(p_uas, float), np.asarray(cp, float)
    dv = float(np.linalg.norm(np.asarray(v_uas, float) - np.asarray(v_overtaken, float)))
    decision = dv * frame
    middle = float(np.sqrt(np.sum((p_uas - cp) ** 2) + margin**2))
    safe = middle + decision + reach_margin
    h = np.asarray(v_overtaken, float)[:2]
    h = h / max(float(np.linalg.norm(h)), 1e-9)
    x, y = np.array([h[0], h[1], 0.0]), np.array([-h[1], h[0], 0.0])
    origin = cp - float((cp - np.asarray(p_overtaken, float)) @ y) * y
    lateral = -(decision + margin)
    return origin + lateral * y, origin + safe * x + lateral * y


def _severity(case: CollisionCase):
    return (-case.margin, SEVERITY[case.encounter], float(case.distance))


@dataclass(frozen=True)
class DetectCollisionCases:
    """(tab. 6.10) Once the own UAS has flown ``settle`` seconds and reached
    ``established_speed`` of its cruise speed (before, at the start, headings say nothing),
    update the case book from this frame's notifications (the peers whose pair could be
    assessed are managed by the rules, the rest stay intruders), re-target roundabout members,
    report unresolved cases (separation below the case margin: handed to the emergency
    avoidance), select the own cases to resolve (own role gives way) by severity. With several
    overtaking roles, or one and another give-way role, the UAS slows to
    ``max(minCruise, min peer speed)`` over those cases (6.202, :func:`overtake_speed`; the spec's
    divergence order from a central UTM does not exist here: it stays at that speed behind them
    while the situation lasts)."""

    code: str = "detect"
    point: DecisionPoint = DecisionPoint.BEFORE_AVOIDANCE_RUN
    priority: int = 0

    def condition(self, ctx: RuleContext) -> bool:
        return True

    def apply(self, ctx: RuleContext, engine: RuleEngine) -> None:
        own_note = ctx.own_note()
        starting = (
            ctx.t < ctx.start + ctx.cfg.settle
            or own_note.speed < ctx.cfg.established_speed * own_note.registration.max_cruise
        )
        if starting and not ctx.book.chains:
            return  # start transient: no approach direction to classify yet, peers stay intruders
        opened, closed = ctx.book.update(ctx.notifications, ctx.t)
        ctx.managed = {a if b == ctx.uas else b for a, b in ctx.book.assessed if ctx.uas in (a, b)}
        for c in opened:
            if ctx.uas in c.ids:
                ctx.record("case_open", c)
        for c in closed:
            if ctx.uas in c.ids:
                ctx.record("case_close", c)
                ctx.emergency.discard(c.other(ctx.uas))
                if ctx.peers is not None:
                    ctx.peers.case_closed(c.other(ctx.uas), ctx.t)
        rbs = {u: rb for rb in ctx.book.roundabouts() for u in rb.members}
        own = []
        for c in ctx.book.active(ctx.uas):
            rb = rbs.get(ctx.uas)
            own.append(as_roundabout(c, rb) if rb is not None else c)
        own = merge_utm(ctx, own)
        for c in own:
            if c.separation < c.margin and (c.ids, c.head) not in ctx.unresolved:  # once per chain
                ctx.unresolved.add((c.ids, c.head))
                ctx.emergency.add(c.other(ctx.uas))
                ctx.record("case_unresolved", c, separation_m=c.separation, margin_m=c.margin)
        giving = [c for c in own if c.role_of(ctx.uas) in RESOLVING]
        if any(c.role_of(ctx.uas) == Role.OVERTAKING for c in giving) and len(giving) > 1:
            speeds = [n.speed for n in ctx.notifications if n.id in {c.other(ctx.uas) for c in giving}]
            ctx.speed = overtake_speed(own_note.registration.min_cruise, speeds)
            ctx.record("overtake_speed", speed_mps=ctx.speed, peers=sorted(c.other(ctx.uas) for c in giving))
        ctx.resolve = sorted(
            (c for c in own if c.role_of(ctx.uas) in RESOLVING and c.other(ctx.uas) not in ctx.emergency), key=_severity
        )
        for c in ctx.resolve:
            role = c.role_of(ctx.uas)
            if role == Role.OVERTAKING and engine.enabled("overtake"):
                _overtake_goal(ctx, c)
                break
            if role == Role.CONVERGING and engine.enabled("converging"):
                _pass_behind_goal(ctx, c)
                break


@dataclass(frozen=True)
class ResolveCollisionCase:
    """(tab. 6.11) In navigation mode, each own case by role: head-on / roundabout, converging,
    overtake (each rule only if enabled); then, with ``widest``, of the trajectories left only
    the one keeping farthest from the head-on / roundabout collision points stays in each cell
    (an overtake and a converging give-way fly to their waypoints instead)."""

    code: str = "resolve"
    point: DecisionPoint = DecisionPoint.TRAJECTORY_RESTRICTIONS
    priority: int = 0

    def condition(self, ctx: RuleContext) -> bool:
        return bool(ctx.resolve) and ctx.run is not None

    def apply(self, ctx: RuleContext, engine: RuleEngine) -> None:
        for case in ctx.resolve:
            ctx.case = case
            engine.call(RESOLVING[case.role_of(ctx.uas)], ctx)
        ctx.case = None
        points = [c.collision_point for c in ctx.resolve if c.role_of(ctx.uas) == Role.ROUNDABOUT]
        if ctx.disabled is not None and ctx.cfg.widest and points:  # of what is left, the widest berth per cell
            tree, pose = ctx.navigation_tree()
            feasible = ctx.current_run().fused.node_ok & ~ctx.disabled
            ctx.disable(
                "widest",
                widest_per_cell(tree, feasible, path_clearance(tree, pose, np.array(points))),
                ctx.resolve[0],
            )


@dataclass(frozen=True)
class Manoeuvre:
    """Head-on (tab. 6.13) and converging (tab. 6.14): right-plane heading and the safety margin
    (case margin + bloat; the give-way UAS of a converging case adds ``converging_extra``)."""

    code: str
    role: Role
    point: None = None
    priority: int = 0

    def condition(self, ctx: RuleContext) -> bool:
        return ctx.case is not None and ctx.case.role_of(ctx.uas) == self.role

    def apply(self, ctx: RuleContext, engine: RuleEngine) -> None:
        extra = ctx.cfg.converging_extra if self.role == Role.CONVERGING else 0.0
        case = ctx.current_case()
        ctx.margin = case.margin + (ctx.cfg.bloat + extra) * ctx.unit
        ctx.record(self.code, case, margin_m=ctx.margin)
        engine.call("right_plane_heading", ctx)
        engine.call("safety_margin", ctx)


@dataclass(frozen=True)
class Overtake:
    """(tab. 6.15) The faster UAS keeps the safety margin around the overtaken UAS' predicted
    position; its divergence / convergence waypoints (flown as the run's goal) are set when the
    case is selected (:func:`_overtake_goal`, before the run)."""

    code: str = "overtake"
    point: None = None
    priority: int = 0

    def condition(self, ctx: RuleContext) -> bool:
        return ctx.case is not None and ctx.case.role_of(ctx.uas) == Role.OVERTAKING

    def apply(self, ctx: RuleContext, engine: RuleEngine) -> None:
        case = ctx.current_case()
        peer = ctx.peer_note(case).adjusted(ctx.current_decision().t_grid)
        ctx.margin = case.margin + ctx.cfg.bloat * ctx.unit
        ctx.record(self.code, case, margin_m=ctx.margin)
        ctx.case = replace(case, collision_point=peer.pos)
        engine.call("safety_margin", ctx)
        ctx.case = case


def _overtake_goal(ctx: RuleContext, case: CollisionCase) -> None:
    """The overtake's waypoint for this frame: divergence until abeam of it, then convergence."""
    own = ctx.own_note()
    peer = ctx.peer_note(case).adjusted(ctx.t)
    margin = case.margin + ctx.cfg.bloat * ctx.unit
    div, conv = overtake_waypoints(
        own.pos, own.vel, peer.pos, peer.vel, case.collision_point, margin, ctx.frame, 2.0 * ctx.length
    )
    h = peer.vel[:2] / max(float(np.linalg.norm(peer.vel[:2])), 1e-9)
    past_div = float((own.pos[:2] - div[:2]) @ h) > -ctx.length
    ctx.goal_override = conv if past_div else div
    ctx.record(
        "overtake_waypoint",
        case,
        divergence_enu=div.tolist(),
        convergence_enu=conv.tolist(),
        target="convergence" if past_div else "divergence",
    )


def pass_behind_point(p_peer, v_peer, p_uas, offset: float) -> np.ndarray | None:
    """The give-way UAS' aim while it is not yet ``offset`` [m] behind the right-of-way UAS
    along the latter's track: the point ``offset`` behind the peer on its track, GCF [m]
    (tab. 6.14: pass behind, then return); None once it is that far behind (back to the mission)
    or when the peer has no horizontal course."""
    p_peer, p_uas = np.asarray(p_peer, float), np.asarray(p_uas, float)
    h = np.asarray(v_peer, float)[:2]
    speed = float(np.linalg.norm(h))
    if speed < 1e-9:
        return None
    h = h / speed
    if float((p_uas[:2] - p_peer[:2]) @ h) <= -offset:
        return None
    return p_peer - offset * np.array([h[0], h[1], 0.0])


def _pass_behind_goal(ctx: RuleContext, case: CollisionCase) -> None:
    """The converging give-way UAS' waypoint for this frame: behind the right-of-way UAS by
    the manoeuvre's margin (:func:`pass_behind_point`). Aiming at the mission goal the path
    selection skirts the margin ball tangentially and turns last; the peer's moving margin then
    closes every path (soft deadlock, emergency)."""
    own = ctx.own_note()
    peer = ctx.peer_note(case).adjusted(ctx.t)
    offset = case.margin + (ctx.cfg.bloat + ctx.cfg.converging_extra) * ctx.unit
    aim = pass_behind_point(peer.pos, peer.vel, own.pos, offset)
    if aim is not None:
        ctx.goal_override = aim
        ctx.record("pass_behind", case, aim_enu=aim.tolist())


@dataclass(frozen=True)
class RightPlaneHeading:
    """(tab. 6.16) Disable navigation trajectories with a point left of the separation plane
    (beyond the config's ``plane_tolerance``, 6.216) or, with the config's ``plane_horizon`` > 0,
    whose linear projection from a movement's end over that horizon enters the left subspace
    (6.217)."""

    code: str = "right_plane_heading"
    point: None = None
    priority: int = 0

    def condition(self, ctx: RuleContext) -> bool:
        return ctx.case is not None and ctx.run is not None

    def apply(self, ctx: RuleContext, engine: RuleEngine) -> None:
        tree, pose = ctx.navigation_tree()
        case = ctx.current_case()
        tol = ctx.cfg.plane_tolerance * ctx.unit
        mask = right_plane_heading_mask(tree, pose, case.collision_point, tol, ctx.cfg.plane_horizon)
        ctx.disable(self.code, mask, case)


@dataclass(frozen=True)
class EnforceSafetyMargin:
    """(tab. 6.17) Ball (uncontrolled airspace) or well-clear barrel (controlled) of radius
    ``ctx.margin`` around the case's collision point, and a ball of the case margin + bloat
    around the peer's linear prediction at every sample time (the point alone does not keep
    the give-way UAS clear of a right-of-way UAS flying through it)."""

    code: str = "safety_margin"
    point: None = None
    priority: int = 0

    def condition(self, ctx: RuleContext) -> bool:
        return ctx.case is not None and ctx.run is not None

    def apply(self, ctx: RuleContext, engine: RuleEngine) -> None:
        (tree, pose), case = ctx.navigation_tree(), ctx.current_case()
        half = ctx.cfg.barrel_half_height if ctx.cfg.airspace == "controlled" else None
        tol = ctx.cfg.plane_tolerance * ctx.unit
        mask = safety_margin_mask(tree, pose, case.collision_point, ctx.margin, half, tol)
        peer = ctx.note(case.other(ctx.uas))
        if peer is not None:  # and around the peer flying on (its separation, not only the point's)
            p = peer.adjusted(ctx.current_decision().t_grid)
            mask |= moving_margin_mask(tree, pose, p.pos, p.vel, case.margin + ctx.cfg.bloat * ctx.unit, tol)
        ctx.disable(self.code, mask, case)


@dataclass(frozen=True)
class CloseCollisionCases:
    """(tab. 6.12) After the run: if the restricted navigation reach set kept no path (soft
    deadlock) and the UAS does not hover it out (:meth:`RulesAvoider._hold`), the previous plan is
    flown on (mission control keeps its buffer); after
    ``deadlock_frames`` such frames in a row the peers of the cases go to the emergency
    avoidance (intruders again). Reports the resolution (mode, planned buffer)."""

    code: str = "close"
    point: DecisionPoint = DecisionPoint.AFTER_AVOIDANCE_RUN
    priority: int = 0

    def condition(self, ctx: RuleContext) -> bool:
        return bool(ctx.resolve) and ctx.decision is not None

    def apply(self, ctx: RuleContext, engine: RuleEngine) -> None:
        d = ctx.current_decision()
        blocked = ctx.path_found is False and not ctx.held
        ctx.deadlock_frames = ctx.deadlock_frames + 1 if blocked else 0
        if blocked:
            handover = ctx.deadlock_frames >= ctx.cfg.deadlock_frames
            if handover:
                for c in ctx.resolve:
                    ctx.emergency.add(c.other(ctx.uas))
            ctx.record(
                "deadlock",
                peers=sorted(c.other(ctx.uas) for c in ctx.resolve),
                frames=ctx.deadlock_frames,
                handover=handover,
            )
        ctx.record(
            "resolution", mode=d.mode.value, buffer=[int(m) for m in d.buffer], cases=[c.record() for c in ctx.resolve]
        )


def roundabout_aim(p_uas, centre, radius: float, lead: float) -> np.ndarray:
    """Where a UAS passing a static weather case like a roundabout aims (GCF [m], the UAS'
    height): on the circle of ``radius`` [m] around ``centre``, counter-clockwise (the centre on
    its left), at the tangent point seen from the UAS or, closer in, ``lead`` [rad] ahead of it
    (a chord of ``lead`` keeps ``radius·cos(lead/2)`` from the centre)."""
    p, c = np.asarray(p_uas, float), np.asarray(centre, float)
    off = p[:2] - c[:2]
    dist = max(float(np.hypot(*off)), 1e-9)
    angle = float(np.arctan2(off[1], off[0])) + max(float(np.arccos(min(radius / dist, 1.0))), lead)
    return np.array([c[0] + radius * np.cos(angle), c[1] + radius * np.sin(angle), p[2]])


@dataclass(frozen=True)
class WeatherCases:
    """(§7.5, tab. 6.9) Before the run: a weather case whose body + band the route to this
    frame's goal crosses is passed like a roundabout, its centre kept on the left at the radius
    body + band + bloat (:func:`roundabout_aim` is flown as the run's goal, unless a collision
    case set one). A static cell where it is; a moving one (intruder-like) where it will be when
    the UAS, flying its route at cruise, is closest to its centre (linear CPA). The restrictions
    follow in :class:`WeatherRestriction`."""

    code: str = "weather"
    point: DecisionPoint = DecisionPoint.BEFORE_AVOIDANCE_RUN
    priority: int = 1

    def condition(self, ctx: RuleContext) -> bool:
        return bool(ctx.weather) and ctx.goal is not None and ctx.goal_override is None

    def apply(self, ctx: RuleContext, engine: RuleEngine) -> None:
        own = ctx.own_note()
        goal = np.asarray(ctx.goal, float)
        route = shapely.LineString([own.pos[:2], goal[:2]])
        ahead = goal - own.pos
        cruise = ahead / max(float(np.linalg.norm(ahead)), 1e-9) * own.registration.max_cruise
        for w in ctx.weather:
            # a moving cell where the UAS, flying its route at cruise, is closest to its centre
            c0 = w.centre + np.array([*w.velocity, 0.0]) * (ctx.t - w.t)
            t_cpa = max(closest_approach(own.pos[:2], cruise[:2], c0[:2], w.velocity)[0], 0.0) if w.moving else 0.0
            if not shapely.dwithin(w.moved(ctx.t + t_cpa), route, w.margin):
                continue
            radius = w.radius + w.margin + ctx.cfg.bloat * ctx.unit
            centre = c0 + np.array([*w.velocity, 0.0]) * t_cpa
            ctx.goal_override = roundabout_aim(own.pos, centre, radius, ROUNDABOUT_LEAD_RAD)
            ctx.events.append(f"rule:weather_roundabout:{w.id}")
            ctx.decisions.append(
                {"rule": "weather_roundabout", "weather_case": w.record(), "aim_enu": ctx.goal_override.tolist()}
            )
            return  # one aim per frame: the first listed cell the route crosses


@dataclass(frozen=True)
class WeatherRestriction:
    """(§7.5) Every weather case restricts the navigation reach set: its body is hard (nodes with
    a sample in it are disabled), its margin band soft (disabled unless that leaves no
    trajectory); a UAS already inside the band keeps its current distance instead. A moving cell
    is handled like an intruder: body and band where the cell is at each sample's time."""

    code: str = "weather_restriction"
    point: DecisionPoint = DecisionPoint.TRAJECTORY_RESTRICTIONS
    priority: int = 1

    def condition(self, ctx: RuleContext) -> bool:
        return bool(ctx.weather) and ctx.run is not None

    def apply(self, ctx: RuleContext, engine: RuleEngine) -> None:
        tree, pose = ctx.navigation_tree()
        t_grid = ctx.current_decision().t_grid
        ok = ctx.current_run().fused.node_ok
        for w in ctx.weather:
            here = float(shapely.distance(w.moved(t_grid), shapely.Point(*pose.origin[:2])))
            band = min(w.margin, here)
            hard, soft = weather_masks(tree, pose, w.body, w.velocity, t_grid - w.t, band)
            before = np.zeros(tree.n_nodes, bool) if ctx.disabled is None else ctx.disabled
            soft_kept = not (ok & ~(before | hard | soft)).any()  # soft: given up only when nothing is left
            ctx.disabled = before | hard if soft_kept else before | hard | soft
            ctx.events.append(f"rule:weather:{w.id}:{'moving' if w.moving else 'static'}")
            ctx.decisions.append(
                {
                    "rule": "weather",
                    "weather_case": w.record(),
                    "band_m": band,
                    "hard_nodes": int((hard & ~before).sum()),
                    "soft_nodes": 0 if soft_kept else int((soft & ~before & ~hard).sum()),
                    "soft_kept": soft_kept,
                }
            )


def make_rules(enabled) -> list:
    """The rule objects of the enabled codes."""
    every = {
        "detect": DetectCollisionCases(),
        "resolve": ResolveCollisionCase(),
        "close": CloseCollisionCases(),
        "head_on": Manoeuvre("head_on", Role.ROUNDABOUT),
        "converging": Manoeuvre("converging", Role.CONVERGING),
        "overtake": Overtake(),
        "right_plane_heading": RightPlaneHeading(),
        "safety_margin": EnforceSafetyMargin(),
        "weather": WeatherCases(),
    }
    extra = [WeatherRestriction()] if "weather" in enabled else []
    return [every[c] for c in enabled] + extra
