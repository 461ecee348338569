"""Collision case of a pair of UAS for one UTM frame (spec §7.4 with the corrections of A-19).

Frames and units: z-up GCF (ENU) [m], velocities [m/s], times sim seconds [s], angles degrees
(the angle of approach α, as in the thesis' thresholds). Steps: adjust both notifications to the
frame time; linear closest point of approach (6.184-6.185 corrected); trajectory intersection of
the movement predictions when one is known (6.187-6.189, midpoint; the other linear); flag when the predicted
distance is within the collision margin (6.186) no later than ``time_margin``; then the
encounter by α (6.190-6.191), the roles and the case's safety margin (6.192-6.194).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from avoidance.utm.notification import Margins, PositionNotification

HEAD_ON_MIN_DEG = 130.0  # 130° <= α <= 180°: head-on
CONVERGING_MIN_DEG = 70.0  # 70° <= α < 130°: converging; below: overtake when the speeds differ, else converging


class Encounter(str, Enum):
    HEAD_ON = "head_on"
    CONVERGING = "converging"
    OVERTAKE = "overtake"


class Role(str, Enum):
    ROUNDABOUT = "roundabout"  # head-on: both diverge right, nobody has right of way
    CONVERGING = "converging"  # gives way (traffic on its right, or lower priority)
    RIGHT_OF_WAY = "right_of_way"
    OVERTAKING = "overtaking"
    OVERTAKEN = "overtaken"  # has right of way


@dataclass(frozen=True, slots=True)
class UtmConfig:
    """Collision-case parameters: ``time_margin`` [s] (how far ahead a closest approach is
    flagged; [D] two grid ranges over the speed, see docs/rules.md), ``speed_tolerance`` [m/s]
    (speeds closer than this are equal: no overtake), ``close_after`` frames without danger
    before a case closes (A-32 hysteresis), ``min_speed`` [m/s] below which a UAS has no
    approach direction (hovering): no case is computed for it (it stays an intruder).
    ``angle_doubt`` [deg] and ``speed_doubt`` [m/s]: how far the two UAS' estimates of α and of
    the speed difference may disagree (each computes the pair from its own estimate and its noisy
    track of the other); a UAS that would give way anywhere within them gives way
    (:func:`pair_roles`)."""

    time_margin: float = 20.0
    speed_tolerance: float = 0.2
    close_after: int = 2
    min_speed: float = 0.0
    angle_doubt: float = 10.0
    speed_doubt: float = 0.1


def closest_approach(p1, v1, p2, v2) -> tuple[float, float, np.ndarray]:
    """Linear CPA (6.184-6.185 corrected): time t* [s] from now (0 when the relative velocity
    vanishes; negative = diverging), distance at t* [m] and collision point = midpoint of both
    positions at t*."""
    p1, v1, p2, v2 = (np.asarray(x, float) for x in (p1, v1, p2, v2))
    dp, dv = p1 - p2, v1 - v2
    vv = float(dv @ dv)
    t = -float(dp @ dv) / vv if vv > 1e-12 else 0.0
    d1, d2 = p1 + v1 * t, p2 + v2 * t
    return t, float(np.linalg.norm(d1 - d2)), 0.5 * (d1 + d2)


def trajectory_min_distance(traj1: np.ndarray, traj2: np.ndarray, times: np.ndarray) -> tuple[float, np.ndarray, float]:
    """Trajectory intersection (6.188-6.189 corrected): both predictions (T, 3) on the same
    times (T,) [s]; minimum distance [m], collision point = midpoint at the minimising time, and
    that time."""
    d = np.linalg.norm(traj1 - traj2, axis=1)
    k = int(np.argmin(d))
    return float(d[k]), 0.5 * (traj1[k] + traj2[k]), float(times[k])


def angle_of_approach(p1_adj, p2_adj, cp) -> float:
    """α [deg] in [0, 180] between the directions from the collision point to both UAS
    (6.190-6.191): 180° = exactly opposite approaches."""
    n1, n2 = np.asarray(p1_adj, float) - cp, np.asarray(p2_adj, float) - cp
    return float(np.degrees(abs(np.arctan2(np.linalg.norm(np.cross(n1, n2)), n1 @ n2))))


def classify(alpha_deg: float, speed1: float, speed2: float, speed_tolerance: float = 0.2) -> Encounter:
    """Encounter by the angle of approach (spec §7.2; T-UT-1): head-on from 130°, converging
    from 70°, below that overtake when the speeds differ by more than ``speed_tolerance`` [m/s],
    else converging (ICAO Annex 2 3.2.2: converging is every approach that is neither head-on nor
    overtaking; at equal speeds two UAS whose courses cross at under 70° close abeam)."""
    if alpha_deg >= HEAD_ON_MIN_DEG:
        return Encounter.HEAD_ON
    if alpha_deg >= CONVERGING_MIN_DEG or abs(speed1 - speed2) <= speed_tolerance:
        return Encounter.CONVERGING
    return Encounter.OVERTAKE


def collision_margin(m1: Margins, m2: Margins) -> float:
    """(6.186): the largest sum of both UAS' margins over the situations [m]."""
    return max(
        m1.universal + m2.universal, m1.head_on + m2.head_on, m1.converging + m2.converging, m1.overtake + m2.overtake
    )


def case_margin(encounter: Encounter, m1: Margins, m2: Margins, roles: tuple[Role, Role]) -> float:
    """Safety margin of an active case [m] (6.192-6.194 corrected: the converging branch uses the
    avoider's converging margin and the right-of-way UAS' universal one)."""
    if encounter == Encounter.HEAD_ON:
        return max(m1.universal + m2.universal, m1.head_on + m2.head_on)
    if encounter == Encounter.CONVERGING:
        row, avoider = (m1, m2) if roles[0] == Role.RIGHT_OF_WAY else (m2, m1)
        return max(row.universal, avoider.converging)
    return max(m1.universal, m2.universal, m1.overtake, m2.overtake)


def traffic_on_right(p_own, cp, p_other) -> bool:
    """Whether ``p_other`` lies right of the own approach line ``p_own -> cp`` (horizontal,
    z-up: a negative cross product)."""
    a = np.asarray(cp, float)[:2] - np.asarray(p_own, float)[:2]
    b = np.asarray(p_other, float)[:2] - np.asarray(p_own, float)[:2]
    return bool(a[0] * b[1] - a[1] * b[0] < 0.0)


GIVES_WAY = frozenset({Role.ROUNDABOUT, Role.CONVERGING, Role.OVERTAKING})


def encounter_roles(
    encounter: Encounter, faster1: bool, right1: bool, priority1: tuple[int, int], priority2: tuple[int, int]
) -> tuple[Role, Role]:
    """Roles of UAS 1 and 2 (§7.4 step 6): head-on both roundabout; overtake: the faster one
    (``faster1``: UAS 1) overtakes; converging: a different category or maneuverability gives the
    higher-priority UAS (smaller ``priority``) the right of way, else the UAS with traffic on its
    right (``right1``: UAS 1) gives way."""
    if encounter == Encounter.HEAD_ON:
        return Role.ROUNDABOUT, Role.ROUNDABOUT
    if encounter == Encounter.OVERTAKE:
        return (Role.OVERTAKING, Role.OVERTAKEN) if faster1 else (Role.OVERTAKEN, Role.OVERTAKING)
    if priority1 != priority2:
        return (Role.RIGHT_OF_WAY, Role.CONVERGING) if priority1 < priority2 else (Role.CONVERGING, Role.RIGHT_OF_WAY)
    return (Role.CONVERGING, Role.RIGHT_OF_WAY) if right1 else (Role.RIGHT_OF_WAY, Role.CONVERGING)


def pair_roles(
    alpha_deg: float,
    speed1: float,
    speed2: float,
    right1: bool,
    side_sure: bool,
    priorities: tuple[tuple[int, int], tuple[int, int]],
    cfg: UtmConfig,
) -> tuple[Encounter, tuple[Role, Role]]:
    """The pair's encounter (at the estimate) and roles, a UAS in doubt giving way. The two UAS
    compute the pair each from its own estimate and its noisy track of the other, so near a
    threshold they can classify it differently; the roles of one classification are always
    complementary (one gives way, or both), but mixed ones need not be (overtaken vs right of way:
    nobody gives way). So each UAS keeps a holding role only if it holds in every classification
    within ``cfg.angle_doubt`` of α and ``cfg.speed_doubt`` of the speed difference (and for either
    side when ``side_sure`` is false); else it takes the nearest give-way role. Whenever the two
    estimates differ by less than the doubts, at least one of the UAS gives way."""
    encounter = classify(alpha_deg, speed1, speed2, cfg.speed_tolerance)
    roles = list(encounter_roles(encounter, speed1 > speed2, right1, *priorities))
    dspeed = speed1 - speed2
    angles, speeds = (0.0, -cfg.angle_doubt, cfg.angle_doubt), (0.0, -cfg.speed_doubt, cfg.speed_doubt)
    doubts = sorted(((da, ds) for da in angles for ds in speeds), key=lambda d: (d[0] != 0.0) + (d[1] != 0.0))
    sides = (right1,) if side_sure else (right1, not right1)
    for da, ds in doubts:
        for side in sides:
            alpha, diff = min(max(alpha_deg + da, 0.0), 180.0), dspeed + ds
            alt = encounter_roles(classify(alpha, diff, 0.0, cfg.speed_tolerance), diff > 0.0, side, *priorities)
            roles = [r if r in GIVES_WAY or a not in GIVES_WAY else a for r, a in zip(roles, alt, strict=True)]
    return encounter, (roles[0], roles[1])


def side_of_traffic(p1, v1, p2, v2, cp, angle_doubt_deg: float) -> tuple[bool, bool]:
    """Whether UAS 2 is on UAS 1's right (:func:`traffic_on_right`), and whether that is sure: the
    offset ``p2 - p1`` is more than ``angle_doubt_deg`` off the mean course ``(v1 + v2) / 2`` (the
    side flips only where the offset runs along that course: one UAS trailing the other)."""
    mean = 0.5 * (np.asarray(v1, float)[:2] + np.asarray(v2, float)[:2])
    off = np.asarray(p2, float)[:2] - np.asarray(p1, float)[:2]
    norm = float(np.linalg.norm(mean) * np.linalg.norm(off))
    sine = abs(float(mean[0] * off[1] - mean[1] * off[0])) / norm if norm > 1e-12 else 0.0
    return traffic_on_right(p1, cp, p2), sine > float(np.sin(np.radians(angle_doubt_deg)))


@dataclass(slots=True)
class CollisionCase:
    """One pair's case in one frame (tabs. 6.7/6.8). ``ids`` and ``roles`` are ordered alike;
    ``collision_point`` GCF [m]; ``distance`` at the closest approach [m], ``t_cpa`` [s] from
    the frame time; ``margin`` the case's safety margin [m]; ``flagged`` = a danger this frame.
    ``head`` is the frame time of the chain's head case (which fixes point and roles)."""

    t: float
    ids: tuple[str, str]
    encounter: Encounter
    alpha_deg: float
    roles: tuple[Role, Role]
    collision_point: np.ndarray
    distance: float
    t_cpa: float
    margin: float
    flagged: bool
    linear: bool = True
    trajectory: bool = False
    head: float | None = None
    separation: float = 0.0  # current distance of the pair [m]
    links: list[float] = field(default_factory=list)

    def role_of(self, uas: str) -> Role:
        return self.roles[self.ids.index(uas)]

    def other(self, uas: str) -> str:
        return self.ids[1 - self.ids.index(uas)]

    @staticmethod
    def from_record(r: dict) -> CollisionCase:
        """The case a :meth:`record` describes (chain links are not recorded)."""
        return CollisionCase(
            r["t"],
            (r["ids"][0], r["ids"][1]),
            Encounter(r["encounter"]),
            r["alpha_deg"],
            (Role(r["roles"][0]), Role(r["roles"][1])),
            np.asarray(r["collision_point_enu"], float),
            r["distance_m"],
            r["t_cpa_s"],
            r["margin_m"],
            r["flagged"],
            linear=not r["trajectory"],
            trajectory=r["trajectory"],
            head=r["head_t"],
            separation=r["separation_m"],
        )

    def record(self) -> dict:
        """JSON-ready values (GCF ENU point)."""
        return {
            "t": self.t,
            "ids": list(self.ids),
            "encounter": self.encounter.value,
            "alpha_deg": self.alpha_deg,
            "roles": [r.value for r in self.roles],
            "collision_point_enu": self.collision_point.tolist(),
            "distance_m": self.distance,
            "t_cpa_s": self.t_cpa,
            "margin_m": self.margin,
            "flagged": self.flagged,
            "trajectory": self.trajectory,
            "head_t": self.head,
            "separation_m": self.separation,
        }


def compute_collision_case(
    n1: PositionNotification,
    n2: PositionNotification,
    t: float,
    cfg: UtmConfig = UtmConfig(),
    gate: float = 1.0,
) -> CollisionCase | None:
    """The case of the pair at frame time ``t`` [s], or None when they cannot meet (different
    flight levels) or one of them is slower than ``gate`` × ``min_speed`` (hovering: no approach
    direction). :class:`~avoidance.utm.cases.CaseBook` passes 1 for a pair in no case, 0.5 for one
    awaiting its confirming frame (a slow UAS' tracked speed fluctuates across ``min_speed``) and
    0 for one whose chain is open (the chain ends by its close rule, not by a hover). ``flagged`` is set when the
    closest approach (trajectory intersection when a prediction is known, else linear) lies
    in [0, time_margin] (trajectories: (0, time_margin], their minimum at the frame time means
    the pair is past it) and within the collision margin (6.186)."""
    if not n1.shares_level(n2) or min(n1.speed, n2.speed) < gate * cfg.min_speed:
        return None
    a1, a2 = n1.adjusted(t), n2.adjusted(t)
    t_cpa, dist, cp = closest_approach(a1.pos, a1.vel, a2.pos, a2.vel)
    trajectory = False
    known = [n.trajectory_t for n in (a1, a2) if n.trajectory is not None and n.trajectory_t is not None]
    if known:  # one filed prediction is enough: the other UAS is then predicted linearly on its times
        times = np.union1d(known[0], known[-1])
        times = times[(times >= t) & (times <= t + cfg.time_margin)]
        if len(times) > 1:
            p1 = np.stack([a1.adjusted(s).pos for s in times])
            p2 = np.stack([a2.adjusted(s).pos for s in times])
            dist, cp, t_min = trajectory_min_distance(p1, p2, times)
            t_cpa, trajectory = t_min - t, True
    m1, m2 = n1.registration.margins, n2.registration.margins
    ahead = t_cpa > 0.0 if trajectory else t_cpa >= 0.0  # a trajectory minimum at the frame time: diverging
    flagged = ahead and t_cpa <= cfg.time_margin and dist <= collision_margin(m1, m2)
    alpha = angle_of_approach(a1.pos, a2.pos, cp)
    right1, side_sure = side_of_traffic(a1.pos, a1.vel, a2.pos, a2.vel, cp, cfg.angle_doubt)
    priorities = (n1.registration.priority(), n2.registration.priority())
    enc, rl = pair_roles(alpha, a1.speed, a2.speed, right1, side_sure, priorities, cfg)
    return CollisionCase(
        t,
        (n1.id, n2.id),
        enc,
        alpha,
        rl,
        cp,
        dist,
        t_cpa,
        case_margin(enc, m1, m2, rl),
        flagged,
        linear=not trajectory,
        trajectory=trajectory,
        separation=float(np.linalg.norm(a1.pos - a2.pos)),
    )
