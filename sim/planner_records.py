"""Planner-specific records in the run log, beside the common ``/<v>/plan`` (each planner type
names its record writer in ``sim.planner_registry``):

- geometric: ``/<v>/plan/candidates`` (every candidate path, its cost terms and the choice)
  when a new set of candidates was generated;
- reach-set: ``/<v>/plan/decision`` (mode, events, cell classes...) and ``/<v>/plan/grid``
  (foxglove.SceneUpdate: the avoidance grid and chosen path, 3D panel); with rules of the air,
  ``/<v>/plan/rules`` (collision cases, roundabouts, every rule decision of the frame);
- MPTP: ``/<v>/plan/map`` (foxglove.GeoJSON: plan, the margin region now (ground frame) and the
  last nowcast's cells at its issue time, Map panel).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from foxglove_schemas_protobuf.GeoJSON_pb2 import GeoJSON

from sim.core.plan import Plan
from sim.geodesy import GeoPoint
from sim.mcap_log import McapLog

_ANY = {"title": "cosim.PlannerRecord", "type": "object", "additionalProperties": True}

# The wall-clock fields (dotted paths) of each planner's records, by channel suffix after
# /<v>/plan: their channels carry metadata wallclock=true and wallclock_fields=<the paths>; every
# other field repeats bit for bit with the scenario and seed.
WALLCLOCK_FIELDS: dict[str, dict[str, tuple[str, ...]]] = {
    "geometric": {
        "": tuple(
            f"diagnostics.t_{s}_s" for s in ("total", "generation", "kinematics", "collision", "cost", "selection")
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


@dataclass(slots=True)
class RecordSink:
    """Where one vehicle's planner records go: the log, the topic prefix ``/<vehicle>/plan``,
    the scenario origin (for geodetic records) and a memory a record writer may keep between
    calls."""

    log: McapLog
    prefix: str
    origin: GeoPoint
    memory: dict[str, Any] = field(default_factory=dict)


def geometric_records(sink: RecordSink, planner: Any, plan: Plan, t: float) -> None:
    c = planner.candidate_log()
    if c is not None and c["t"] != sink.memory.get("candidates_t"):
        sink.memory["candidates_t"] = c["t"]
        sink.log.write_json(
            f"{sink.prefix}/candidates",
            t,
            c,
            {**_ANY, "title": "cosim.GeometricCandidates"},
            wallclock_metadata("geometric", "/candidates"),
        )


def reachset_records(sink: RecordSink, planner: Any, plan: Plan, t: float) -> None:
    from avoidance.reachset.record import decision_record, scene_update

    d = planner.last_decision
    if d is None:
        return
    sink.log.write_json(
        f"{sink.prefix}/decision",
        t,
        decision_record(d),
        {**_ANY, "title": "cosim.ReachSetDecision"},
        wallclock_metadata("reachset", "/decision"),
    )
    sink.log.write_proto(f"{sink.prefix}/grid", t, scene_update(d, sink.log.epoch_ns / 1e9 + t))
    rules = getattr(planner, "rules_record", None)
    if rules is not None and rules["t"] == t:
        sink.log.write_json(f"{sink.prefix}/rules", t, rules, {**_ANY, "title": "cosim.RulesOfAir"})


def mptp_records(sink: RecordSink, planner: Any, plan: Plan, t: float) -> None:
    from sim.plan_geojson import plan_geojson

    timeline = planner.timeline  # the last nowcast as the planner sees it
    issued = timeline.snapshots[0] if timeline is not None else None  # its cells at issue time
    doc = plan_geojson(plan, sink.origin, planner.margins_at(t), issued)  # margins on the ground, now
    sink.log.write_proto(f"{sink.prefix}/map", t, GeoJSON(geojson=doc))
