"""Decision records (plain dicts of lists, for JSON/MCAP) and the Foxglove ``SceneUpdate`` of the
grid and the chosen path (spec §11.6).

Frames: records and scenes are in the project's NED frame [m] (Foxglove frame ``ned``, which the
vehicle log relates to ``world``); per-cell arrays are in flat cell order (reshape (I, J, K)).
"""

from __future__ import annotations

import numpy as np
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.CubePrimitive_pb2 import CubePrimitive
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.Point3_pb2 import Point3
from foxglove_schemas_protobuf.Pose_pb2 import Pose
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
from google.protobuf.duration_pb2 import Duration
from google.protobuf.timestamp_pb2 import Timestamp

from avoidance.reachset.frames import from_polar
from avoidance.reachset.fusion import SpaceClass
from avoidance.reachset.mission import Decision
from sim.core.frames import enu_to_ned, euler_to_quat

NED_FRAME = "ned"
CLASS_COLORS = {
    SpaceClass.FREE: (0.2, 0.8, 0.2, 0.05),
    SpaceClass.UNCERTAIN: (0.5, 0.5, 0.5, 0.25),
    SpaceClass.OCCUPIED: (0.9, 0.1, 0.1, 0.6),
    SpaceClass.CONSTRAINED: (1.0, 0.6, 0.0, 0.5),
}


def decision_record(d: Decision) -> dict:
    """Everything one decision frame decided, as JSON-ready values."""
    rec = {
        "t": d.t,
        "t_grid": d.t_grid,
        "mode": d.mode.value,
        "events": list(d.events),
        "goal_index": d.goal_index,
        "executing": d.executing,
        "buffer": [int(m) for m in d.buffer],
        "status": d.status,
        "complete": d.complete,
        "grid_origin_ned": enu_to_ned(d.pose.origin).tolist(),
        "grid_heading_gcf": d.pose.psi,
        "runs": [r.categories.name for r in d.runs],
        "selected": d.runs[d.selected].categories.name if d.selected >= 0 else "",
        "runtime_s": d.runtime_s,
    }
    run = d.run
    if run is not None:
        f = run.fused
        rec.update(
            {
                "chosen_node": run.path.node,
                "chosen_cell": run.path.cell,
                "error": run.path.error,
                "feasible_nodes": int(f.node_ok.sum()),
                "cells": {
                    "visibility": f.visibility.tolist(),
                    "obstacle": f.obstacle.tolist(),
                    "map": f.map.tolist(),
                    "intruder": f.intruder.tolist(),
                    "constraint": f.constraint.tolist(),
                    "threat": f.threat.tolist(),
                    "class": f.space_class.astype(int).tolist(),
                    "reachable": f.reachable.astype(int).tolist(),
                },
            }
        )
    if d.reference is not None:
        rec["reference_ned"] = enu_to_ned(d.reference.positions).tolist()
        rec["reference_t"] = d.reference.times.tolist()
    return rec


def _stamp(t_log: float) -> Timestamp:
    sec = int(np.floor(t_log))
    return Timestamp(seconds=sec, nanos=round((t_log - sec) * 1e9) % 1_000_000_000)


def _color(rgba) -> Color:
    return Color(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])


def scene_update(d: Decision, t_log: float, entity_id: str = "reachset", show_free: bool = False) -> SceneUpdate:
    """A ``foxglove.SceneUpdate`` in frame ``ned``: one cube per grid cell (coloured by space
    class, free cells only if ``show_free``) oriented along the cell's ray, and the reference
    trajectory as a line strip (the chosen path)."""
    ent = SceneEntity(timestamp=_stamp(t_log), frame_id=NED_FRAME, id=entity_id, lifetime=Duration(seconds=0))
    run = d.run
    if run is not None and d.grid is not None:
        g = d.grid
        cls = run.fused.space_class
        for c in np.flatnonzero(cls != SpaceClass.FREE) if not show_free else range(g.n_cells):
            lo, hi = g.lower[c], g.upper[c]
            mid = g.centers_polar[c]
            size = (hi[0] - lo[0], mid[0] * (hi[1] - lo[1]), mid[0] * (hi[2] - lo[2]))
            centre = enu_to_ned(d.pose.to_gcf(from_polar(mid)))
            yaw_ned = np.pi / 2 - (d.pose.psi + mid[1])  # cell ray heading in NED
            pitch_ned = mid[2]  # nose-up positive in FRD/NED Euler
            qw, qx, qy, qz = euler_to_quat(0.0, pitch_ned, yaw_ned)
            q = Quaternion(x=qx, y=qy, z=qz, w=qw)
            ent.cubes.append(
                CubePrimitive(
                    pose=Pose(position=Vector3(x=centre[0], y=centre[1], z=centre[2]), orientation=q),
                    size=Vector3(x=size[0], y=size[1], z=size[2]),
                    color=_color(CLASS_COLORS[SpaceClass(int(cls[c]))]),
                )
            )
    if d.reference is not None:
        pts = enu_to_ned(d.reference.positions)
        ent.lines.append(
            LinePrimitive(
                type=LinePrimitive.LINE_STRIP,
                thickness=0.1,
                scale_invariant=False,
                points=[Point3(x=p[0], y=p[1], z=p[2]) for p in pts],
                color=_color((0.1, 0.4, 1.0, 1.0)),
                pose=Pose(orientation=Quaternion(w=1.0)),
            )
        )
    return SceneUpdate(entities=[ent])
