"""MPTP — model predictive trajectory planner among moving storm polygons (seed 002, Mothes).

Frames and units: local-level NED from the scenario origin [m]; every horizontal shape is a
shapely geometry in (north, east) [m]; times are sim seconds [s]; courses are radians from north,
positive towards east. The pipeline of one replan (see docs/mptp.md):

    nowcast (StormSnapshot list) -> margins -> Minkowski interpolation -> ObstacleTimeline
    -> time-dependent A* over estimated free state spaces (PSTM) -> Trajectory -> Plan
"""

from guidance.mptp.config import MptpConfig
from guidance.mptp.planner import MptpPlanner

__all__ = ["MptpConfig", "MptpPlanner"]
