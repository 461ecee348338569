"""Planner-specific records in the run log, beside the common ``/<v>/plan``:

- geometric: ``/<v>/plan/candidates`` (every candidate path, its cost terms and the choice)
  when a new set of candidates was generated;
- reach-set: ``/<v>/plan/decision`` (mode, events, cell classes...) and ``/<v>/plan/grid``
  (foxglove.SceneUpdate: the avoidance grid and chosen path, 3D panel); with rules of the air,
  ``/<v>/plan/rules`` (collision cases, roundabouts, every rule decision of the frame);
- MPTP: ``/<v>/plan/map`` (foxglove.GeoJSON: plan, margin polygons, nowcast storms, Map panel).
"""

from __future__ import annotations

from foxglove_schemas_protobuf.GeoJSON_pb2 import GeoJSON

from sim.frames import GeoPoint
from sim.mcap_log import McapLog

_ANY = {"title": "cosim.PlannerRecord", "type": "object", "additionalProperties": True}

# The wall-clock fields (dotted paths) of each planner's records, by channel suffix after
# /<v>/plan: their channels carry metadata wallclock=true and wallclock_fields=<the paths>; every
# other field repeats bit for bit with the scenario and seed.
WALLCLOCK_FIELDS: dict[str, dict[str, tuple[str, ...]]] = {
    "geometric": {
        "": tuple(
            f"diagnostics.t_{step}_s"
            for step in ("total", "generation", "kinematics", "collision", "cost", "selection")
        ),
        "/candidates": ("timings_s",),
    },
    "reachset": {"": ("diagnostics.runtime_ms",), "/decision": ("runtime_s",)},
    "mptp": {"": ("diagnostics.runtime_s", "diagnostics.weather_s")},
}


def wallclock_metadata(planner: str, suffix: str) -> dict[str, str]:
    """Channel metadata marking the wall-clock fields of ``planner``'s records on
    ``/<v>/plan<suffix>`` (empty when they have none)."""
    fields = WALLCLOCK_FIELDS.get(planner, {}).get(suffix)
    return {"wallclock": "true", "wallclock_fields": ",".join(fields)} if fields else {}


class PlannerLogger:
    def __init__(self, log: McapLog, vehicle: str, origin: GeoPoint):
        self.log, self.origin, self.prefix = log, origin, f"/{vehicle}/plan"
        self._last_candidates_t: float | None = None

    def write(self, planner, plan, t: float) -> None:
        name = getattr(planner, "name", "")
        if name == "geometric":
            c = planner.candidate_log()
            if c is not None and c["t"] != self._last_candidates_t:
                self._last_candidates_t = c["t"]
                self.log.write_json(
                    f"{self.prefix}/candidates",
                    t,
                    c,
                    {**_ANY, "title": "cosim.GeometricCandidates"},
                    wallclock_metadata(name, "/candidates"),
                )
        elif name == "reachset" and planner.last_decision is not None:
            from avoidance.reachset.record import decision_record, scene_update

            d = planner.last_decision
            self.log.write_json(
                f"{self.prefix}/decision",
                t,
                decision_record(d),
                {**_ANY, "title": "cosim.ReachSetDecision"},
                wallclock_metadata(name, "/decision"),
            )
            self.log.write_proto(f"{self.prefix}/grid", t, scene_update(d, self.log.epoch_ns / 1e9 + t))
            rules = getattr(planner, "rules_record", None)
            if rules is not None and rules["t"] == t:
                self.log.write_json(f"{self.prefix}/rules", t, rules, {**_ANY, "title": "cosim.RulesOfAir"})
        elif name == "mptp":
            from guidance.mptp.geojson import plan_geojson

            timeline = getattr(planner, "timeline", None)
            margins = timeline.shape_at(t) if timeline is not None else None  # margin-grown storms now
            self.log.write_proto(f"{self.prefix}/map", t, GeoJSON(geojson=plan_geojson(plan, self.origin, margins)))
