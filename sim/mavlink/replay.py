"""Streaming a recorded run (our MCAP log) to a GCS over MAVLink, at 1x, Nx or full speed.

Each vehicle of the log gets its own :class:`~sim.mavlink.bridge.VehicleLink` (system id = its
rank in name order + 1, GCS port = ``base_port`` + rank, as in a live run) and is published
through the same ``publish`` path as a live run, from ``/<v>/truth/state`` (cosim.VehicleState)
and ``/<v>/mission/status`` (the waypoint being flown to). The origin, airframe kinds and missions
come from the ``scenario.toml`` attached to the log; without it the origin is taken at the first
state's position with the altitude of the local NED origin (exact for relative altitudes, only
approximate for HOME_POSITION's latitude/longitude), vehicles are shown as fixed-wing and a
mission download is empty. Replayed vehicles are shown armed in AUTO; commands a GCS sends are
answered by the links but not acted on (an info event says so).

The log must be a finished one (``read_info`` works); a log damaged part-way stops the replay at
the damage with a warning event, and what was before it has been streamed.

Command line: ``python -m sim.mavlink.replay LOG.mcap [--speed N] [--port 14550] ...``.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from aircraft.registry import get_airframe
from sim.geodesy import GeoPoint, ned_to_geodetic
from sim.mavlink.bridge import EventFn, LinkConfig, VehicleLink
from sim.mavlink.mission import Waypoint
from sim.mavlink.pacing import WallClockPacer
from sim.mcap_read import LogReadError, iter_messages, log_content, read_attached_scenario, read_info
from sim.scenario import Scenario
from sim.vehicle_log import state_from_dict


@dataclass
class ReplayResult:
    """What was streamed: truth states published per vehicle, the sim time span [s], the wall
    time taken [s], each link's anomaly counters, and whether the whole log was read."""

    states: dict[str, int] = field(default_factory=dict)
    sim_start_s: float = math.nan
    sim_end_s: float = math.nan
    wall_s: float = 0.0
    stats: dict[str, Counter] = field(default_factory=dict)
    complete: bool = True


def _attached_scenario(path: Path, event: EventFn) -> Scenario | None:
    """The scenario attached to the log, or ``None`` (with a warning) if absent or unreadable."""
    try:
        sc = read_attached_scenario(path)
    except Exception as exc:  # noqa: BLE001 - damaged attachment, bad TOML, stale schema: all optional
        event(
            f"replay: attached scenario unusable ({type(exc).__name__}: {exc}); origin taken from the first state",
            "warning",
        )
        return None
    if sc is None:
        event("replay: the log has no scenario.toml attachment; origin taken from the first state", "warning")
    return sc


def _mission(sc: Scenario, name: str) -> list[Waypoint]:
    """A scenario vehicle's waypoints (north, east [m], altitude MSL [m]) as (lat, lon, alt)."""
    origin = sc.origin_point
    v = next((v for v in sc.vehicle if v.name == name), None)
    if v is None:
        return []
    ned = np.array([[w.north, w.east, origin.alt_m - w.altitude] for w in v.mission.waypoints])
    lat, lon, alt = ned_to_geodetic(ned, origin)
    return [(float(a), float(b), float(c)) for a, b, c in zip(lat, lon, alt, strict=False)]


def replay_to_gcs(
    path: str | Path,
    *,
    speed: float | None = 1.0,
    gcs_host: str = "127.0.0.1",
    base_port: int = 14550,
    rate_hz: float = 4.0,
    vehicles: Sequence[str] | None = None,
    on_event: EventFn | None = None,
    should_stop: Callable[[], bool] | None = None,
) -> ReplayResult:
    """Stream the log at ``path`` to the GCS: ``speed`` times wall time (``None``: as fast as
    possible), telemetry at ``rate_hz`` of sim time. ``vehicles`` limits the replay to those
    names (system ids and ports still follow the rank among all vehicles of the log).
    ``should_stop()`` is checked after every state (e.g. a Ctrl-C flag). Raises LogReadError if
    the file is not a readable finished log."""
    path = Path(path)
    event: EventFn = on_event or (lambda text, level: None)
    info = read_info(path)
    all_names = sorted(t.topic.split("/")[1] for t in info.topics if t.topic.endswith("/truth/state"))
    names = [n for n in all_names if vehicles is None or n in vehicles]
    unknown = sorted(set(vehicles or ()) - set(all_names))
    if unknown:
        raise ValueError(f"{path}: no vehicle {', '.join(unknown)} in the log (has: {', '.join(all_names)})")
    sc = _attached_scenario(path, event)
    origin = sc.origin_point if sc is not None else None
    kinds = {v.name: get_airframe(v.aircraft).kind for v in sc.vehicle} if sc is not None else {}
    result = ReplayResult(states=dict.fromkeys(names, 0))
    links: dict[str, VehicleLink] = {}
    pacer = WallClockPacer(speed) if speed else None
    wall0 = time.monotonic()
    try:
        for n in names:
            cfg = LinkConfig.for_vehicle(
                all_names.index(n), kinds.get(n, "fixed_wing"), gcs_host=gcs_host, base_port=base_port, rate_hz=rate_hz
            )
            links[n] = VehicleLink(cfg, on_event)
            if sc is not None:
                links[n].set_mission(_mission(sc, n))
        current = dict.fromkeys(names, 0)
        topics = [f"/{n}/{s}" for n in names for s in ("truth/state", "mission/status")]
        for topic, t, msg in iter_messages(path, topics):
            name = topic.split("/")[1]
            with log_content(path):
                if topic.endswith("/mission/status"):
                    current[name] = int(msg["next_waypoint"])
                    continue
                state = state_from_dict(msg)
            if origin is None:
                origin = GeoPoint(state.lat_deg, state.lon_deg, state.alt_msl_m + float(state.pos_ned[2]))
            if pacer is not None:
                pacer.pace(t)
            link = links[name]
            link.publish(t, state, current[name], True, "AUTO", [], origin)
            if link.poll():
                event(f"replay: commands from the GCS to {name} are not acted on", "info")
            result.states[name] += 1
            result.sim_start_s = t if math.isnan(result.sim_start_s) else result.sim_start_s
            result.sim_end_s = t
            if should_stop is not None and should_stop():
                result.complete = False
                break
    except LogReadError as exc:
        result.complete = False
        event(f"replay stopped early: {exc}", "warning")
    finally:
        result.wall_s = time.monotonic() - wall0
        for n, link in links.items():
            result.stats[n] = Counter(link.stats)
            link.close()
    return result


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m sim.mavlink.replay",
        description="Stream a recorded run to a MAVLink GCS (QGroundControl, MAVProxy).",
    )
    ap.add_argument("log", type=Path, help="run log (.mcap)")
    ap.add_argument("--speed", type=float, default=1.0, help="times wall clock; 0 = as fast as possible")
    ap.add_argument("--host", default="127.0.0.1", help="GCS host (default 127.0.0.1)")
    ap.add_argument("--port", type=int, default=14550, help="GCS port of the first vehicle; vehicle k uses port+k")
    ap.add_argument("--rate", type=float, default=4.0, help="telemetry rate [Hz of sim time]")
    ap.add_argument("--vehicle", action="append", help="replay only this vehicle (repeatable)")
    args = ap.parse_args(argv)

    def show(text: str, level: str) -> None:
        if level != "debug":
            print(f"[{level}] {text}", file=sys.stderr)

    try:
        res = replay_to_gcs(
            args.log,
            speed=args.speed or None,
            gcs_host=args.host,
            base_port=args.port,
            rate_hz=args.rate,
            vehicles=args.vehicle,
            on_event=show,
        )
    except (LogReadError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    for name, n in res.states.items():
        print(f"{name}: {n} states, anomalies {dict(res.stats[name]) or 'none'}")
    print(
        f"sim {res.sim_start_s:.1f}..{res.sim_end_s:.1f} s streamed in {res.wall_s:.1f} s wall"
        + ("" if res.complete else " (stopped early)")
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
