"""Threat collection for one decision (spec §6.2 step 4): the project's sensed threats
(``sim.core.plan.Threats``, NED) -> per-source cell ratings (``ThreatParts``) of a grid placed
at ``pose`` at time ``t_grid`` (the next decision time), and the situation events (step 5).

Mapping of the project's threat types (decision D-5): LiDAR scan -> detected obstacles and
visibility; ``PrismObstacle`` and static ``SphereThreat`` -> map obstacles; ``IntruderTrack`` and
moving ``SphereThreat`` -> intruders, all with ``cfg.intruders`` (default line + body + time, the
setting of the thesis' emergency scenarios S6-S8, whose intruders are non-cooperative but broadcast
ADS-B; the cone preset is ``IntruderModelConfig.non_cooperative()``); ``Geofence`` -> static
constraints; the newest ``StormSnapshot`` not after ``t_grid`` -> moving constraints.
"""

from __future__ import annotations

import numpy as np

from avoidance.reachset.config import AvoidanceConfig
from avoidance.reachset.frames import GridPose
from avoidance.reachset.fusion import ThreatParts
from avoidance.reachset.grid import AvoidanceGrid
from avoidance.reachset.threats.constraints import Constraint, classify, from_geofence, from_storm
from avoidance.reachset.threats.intruders import IntruderModel, intruder_motion
from avoidance.reachset.threats.lidar import lidar_ratings
from avoidance.reachset.threats.map_obstacles import MapObstacle, map_rating
from avoidance.reachset.tree import ReachSetTree
from sim.core.plan import Threats
from sim.core.threats import IntruderTrack


class Assessor:
    """Writes the sensed threats into the grid for a given reach set (its UAS entry/leave times
    drive the intruder time rates and the moving constraints)."""

    def __init__(self, grid: AvoidanceGrid, tree: ReachSetTree, cfg: AvoidanceConfig):
        self.grid, self.tree, self.cfg = grid, tree, cfg
        self.uas_entry, self.uas_leave = tree.uas_entry_leave()
        self.intruder_model = IntruderModel(grid, self.uas_entry, self.uas_leave, cfg.intruders)

    def constraints(self, threats: Threats, t_grid: float) -> list[Constraint]:
        out = [from_geofence(g, self.cfg.constraints.safety_margin) for g in threats.geofences]
        storms = sorted(threats.storms, key=lambda s: s.t)
        usable = [s for s in storms if s.t <= t_grid] or storms[:1]
        if usable:
            out += from_storm(usable[-1], self.cfg.constraints.safety_margin)
        return out

    def assess(self, pose: GridPose, t_grid: float, threats: Threats) -> ThreatParts:
        grid, cfg = self.grid, self.cfg
        parts = ThreatParts.empty(grid.n_cells)
        if threats.lidar is not None:
            obstacle, visibility = lidar_ratings(grid, pose, threats.lidar, cfg.lidar)
            parts.obstacle, parts.visibility = obstacle[None], visibility[None]
        moving = [s for s in threats.spheres if np.any(np.asarray(s.vel_ned) != 0.0)]
        static = [s for s in threats.spheres if not np.any(np.asarray(s.vel_ned) != 0.0)]
        obstacles = [MapObstacle.from_prism(p, cfg.map.safety_margin) for p in threats.obstacles]
        obstacles += [MapObstacle.from_sphere(s, cfg.map.safety_margin) for s in static]
        parts.map = map_rating(grid, pose, obstacles, cfg.map)
        tracks = list(threats.intruders) + [
            IntruderTrack(s.id, s.t, s.center_ned, s.vel_ned, s.radius_m) for s in moving
        ]
        parts.intruder_motion = intruder_motion(pose, t_grid, tracks, cfg.intruders.body_margin)
        parts.give_way_turn_rate = cfg.intruders.give_way_turn_rate
        parts.vertical_margin = cfg.intruders.vertical_margin
        parts.intruders = self.intruder_model.ratings(parts.intruder_motion)
        parts.hard, parts.soft = classify(
            grid, pose, self.constraints(threats, t_grid), cfg.constraints, t_grid, self.uas_leave
        )
        return parts


def situation_events(parts: ThreatParts, threshold: float) -> list[str]:
    """Mode-switching events of step 5: threats whose impact area intersects the grid."""
    events = []
    if (parts.obstacle >= threshold).any() or (parts.map >= threshold).any():
        events.append("obstacle")
    if (parts.intruders >= threshold).any():
        events.append("intruder")
    if parts.hard.any():
        events.append("hard_constraint")
    if parts.soft.any():
        events.append("soft_constraint")
    return events
