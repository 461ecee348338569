"""The world of one run: vehicles, traffic objects, weather, map obstacles and geofences,
faults, and what each vehicle senses of the rest.

Seeds: one ``numpy.random.SeedSequence`` from the scenario seed spawns independent streams for
every vehicle (JSBSim turbulence, sensors), every vehicle's surveillance sensor and the weather,
so one seed fixes the whole run and adding a vehicle leaves the others' streams unchanged.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Collection
from functools import partial

import numpy as np
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

from sim import log_schemas as S
from sim.broad_phase import relevant
from sim.contacts import Bodies, ContactMonitor, Crash, GroundWatch
from sim.environment import geofence, obstacle_prism
from sim.faults import FaultSchedule
from sim.geodesy import ned_to_geodetic
from sim.hull import Hull, load_hull
from sim.mcap_log import McapLog
from sim.peer_link import PeerNetwork
from sim.perception import Perception
from sim.planner_registry import planner_awareness
from sim.scenario import Scenario, UtmLink
from sim.scheduler import LockstepScheduler, Stage
from sim.sensors.lidar import Lidar
from sim.sensors.truth import TruthSampler
from sim.traffic import TrafficObject
from sim.utm_airspace import UtmAirspace
from sim.utm_link import Link
from sim.vehicle import Vehicle
from sim.vehicle_log import NED_FRAME, write_map
from sim.weather import WeatherService, storms_geojson


def seed_streams(seed: int) -> tuple:
    """The run's independent seed streams: vehicles, surveillance sensing, weather, LiDARs."""
    return tuple(np.random.SeedSequence(seed).spawn(4))


def link_streams(seed: int, n: int) -> list[np.random.SeedSequence]:
    """The C2/UTM links' streams, one per vehicle (a fifth child of the run's seed: the other
    four streams are unchanged by it)."""
    return np.random.SeedSequence(seed).spawn(5)[4].spawn(n)


def peer_link_streams(seed: int, n: int) -> list[np.random.SeedSequence]:
    """The vehicle-to-vehicle links' streams, one per vehicle (a sixth child of the run's seed:
    the other five are unchanged by it)."""
    return np.random.SeedSequence(seed).spawn(6)[5].spawn(n)


def _link(c: UtmLink, ss: np.random.SeedSequence) -> Link:
    return Link(c.latency, c.loss, tuple((o.start, o.end) for o in c.outage), np.random.default_rng(ss))


def weather_seed(weather_ss: np.random.SeedSequence) -> int:
    return int(weather_ss.generate_state(1)[0])


class World:
    def __init__(self, scenario: Scenario, log: McapLog):
        self.scenario = scenario
        self.log = log
        self.origin = scenario.origin_point
        n = len(scenario.vehicle)
        vehicle_ss, sensing_ss, weather_ss, lidar_ss = seed_streams(scenario.seed)
        vehicle_seeds = vehicle_ss.generate_state(n, dtype=np.uint32)
        self.vehicles = [
            Vehicle(v, self.origin, log, int(s), scenario.wind)
            for v, s in zip(scenario.vehicle, vehicle_seeds, strict=False)
        ]
        self.objects = [TrafficObject(c, self.origin) for c in scenario.object]
        self.obstacles = [obstacle_prism(c, self.origin.alt_m) for c in scenario.obstacle]
        self.fences = [geofence(c, self.origin.alt_m) for c in scenario.geofence]
        for v in self.vehicles:
            v.threats.obstacles, v.threats.geofences = self.obstacles, self.fences  # known from the map
        has_traffic = n > 1 or bool(self.objects)
        self.awareness: list[tuple[float, float] | None] = [
            planner_awareness(v.cfg.planner.type, v.planner) for v in self.vehicles
        ]  # what each planner needs sensed (sim/broad_phase.py); None: everything
        self._cruise = np.array([v.mission.cruise_speed for v in self.vehicles])
        self.perception = (
            {
                v.name: Perception(scenario.surveillance, np.random.default_rng(ss))
                for v, ss in zip(self.vehicles, sensing_ss.spawn(n), strict=False)
            }
            if has_traffic
            else {}
        )
        self.weather = (
            WeatherService(scenario.weather, weather_seed(weather_ss), scenario.origin_point)
            if scenario.weather is not None
            else None
        )
        self.faults = FaultSchedule(scenario.fault, {v.name: v for v in self.vehicles}, log)
        self.lidars = {
            v.name: (Lidar(c.lidar, self.obstacles, np.random.default_rng(ss)), TruthSampler(v.plant))
            for v, c, ss in zip(self.vehicles, scenario.vehicle, lidar_ss.spawn(n), strict=False)
            if c.lidar is not None
        }
        hulls: dict[str, Hull] = {}
        watches = []
        for v in self.vehicles:
            hull = hulls.setdefault(v.airframe.name, load_hull(v.airframe.jsbsim_file))
            watches.append(GroundWatch(hull, v.airframe.crash_sink_mps))
            watches[-1].attach(v.plant)
        self.contacts = ContactMonitor(
            [v.name for v in self.vehicles],
            np.array([v.airframe.radius_m for v in self.vehicles]),
            watches,
            self.obstacles,
        )
        self.crashes: list[Crash] = []
        self.utm = self._airspace(scenario, log)
        self.peers = self._peer_network(scenario, log)
        write_map(log, self.obstacles, self.fences, self.origin)
        log.metadata("vehicles", {v.name: v.airframe.kind for v in self.vehicles})

    @property
    def contact_hz(self) -> int:
        """Rate of the crash checks: the fastest control rate (a sub-multiple of every plant rate)."""
        return max(v.airframe.control_hz for v in self.vehicles)

    @property
    def base_hz(self) -> int:
        """The scheduler's base rate: the least common multiple of the plant rates."""
        return math.lcm(*[v.airframe.plant_hz for v in self.vehicles])

    def schedule(self, sched: LockstepScheduler) -> None:
        log_hz = self.scenario.logging.rate_hz
        sched.add_task("world.contacts", self.contact_hz, Stage.ENVIRONMENT, self.check_contacts)
        if self.scenario.fault:
            sched.add_task("faults", log_hz, Stage.SENSE, self.faults.tick)
        if self.perception or self.weather is not None:
            sched.add_task("world.sense", log_hz, Stage.SENSE, self.sense)
        for v in self.vehicles:
            v.schedule(sched, log_hz)
            if v.name in self.lidars:
                sched.add_task(
                    f"{v.name}.lidar", self.lidars[v.name][0].cfg.rate_hz, Stage.SENSE, partial(self._scan, v)
                )
        if self.utm is not None:
            sched.add_task("utm", log_hz, Stage.SENSE, self.utm.tick)
        if self.peers is not None:
            sched.add_task("utm.peers", log_hz, Stage.SENSE, self.peers.tick)
        if self.objects:
            sched.add_task("world.log", log_hz, Stage.LOG, self._log_objects)
        if len(self.vehicles) > 1:
            sched.add_task("world.separation", log_hz, Stage.LOG, self._log_separation)

    def all_complete(self, names: Collection[str] | None = None) -> bool:
        """Whether the missions of the vehicles ``names`` (default: every vehicle) are complete."""
        return all(v.mission.complete for v in self.vehicles if names is None or v.name in names)

    def crashed(self) -> bool:
        return bool(self.crashes)

    def check_contacts(self, t: float) -> None:
        """Crashes from the true states (``sim.contacts``), each logged as a ``crash`` event and
        on ``/world/crash``."""
        pos, vel = zip(*[v.plant.kinematics() for v in self.vehicles], strict=True)
        live = [o for o in self.objects if o.exists(t)]
        others = Bodies(
            [o.id for o in live],
            np.array([o.position(t) for o in live]).reshape(-1, 3),
            np.array([o.v for o in live]).reshape(-1, 3),
            np.array([o.radius_m for o in live]),
        )
        found = self.contacts.check(t, np.array(pos), np.array(vel), others)
        for c in found:
            self.log.event(t, f"{c.vehicle}: crash: {c.describe()}", "error", c.vehicle)
            self.log.write_json(
                "/world/crash", t, c.record(), S.CRASH, {"frame": "local-level NED from the scenario origin"}
            )
        self.crashes += found

    def _airspace(self, scenario: Scenario, log: McapLog) -> UtmAirspace | None:
        """The UTM authorities (scenario ``utm``): one per airspace cluster, or one over the
        whole airspace; each vehicle on its modelled link (``vehicle.utm_link``), the same to every
        authority. None without ``[utm]``."""
        if scenario.utm is None:
            return None
        streams = link_streams(scenario.seed, len(scenario.vehicle))
        links = {v.name: _link(v.utm_link or UtmLink(), ss) for v, ss in zip(scenario.vehicle, streams, strict=True)}
        peered = frozenset(v.name for v in scenario.vehicle if v.peer_link is not None)
        return UtmAirspace(scenario.utm, self.vehicles, links, log, self.origin.alt_m, scenario.logging.rate_hz, peered)

    def _peer_network(self, scenario: Scenario, log: McapLog) -> PeerNetwork | None:
        """The vehicle-to-vehicle links (``vehicle.peer_link``; they need ``[utm]``), None without."""
        streams = peer_link_streams(scenario.seed, len(scenario.vehicle))
        links = {
            v.name: _link(v.peer_link, ss)
            for v, ss in zip(scenario.vehicle, streams, strict=True)
            if v.peer_link is not None
        }
        if not links or scenario.utm is None:
            return None
        return PeerNetwork(self.vehicles, links, scenario.utm.frame, log, scenario.logging.rate_hz)

    # -- sensing the rest of the world ---------------------------------------------------------
    def sense(self, t: float) -> None:
        """Weather nowcasts and traffic tracks into every vehicle's threats."""
        if self.weather is not None and self.weather.update(t):
            if self.utm is not None and self.scenario.utm is not None and self.scenario.utm.weather:
                self.utm.set_storms(self.weather.nowcast)  # the authorities' feed: weather cases in directives
            else:
                for v in self.vehicles:
                    v.threats.storms = self.weather.nowcast
            truth = self.weather.truth(t)
            self.log.write_proto("/world/weather/storms", t, _geojson(storms_geojson(truth, self._lonlat)))
        if not self.perception:
            return
        bodies = {v.name: (v.plant.truth(), v.airframe.radius_m, True) for v in self.vehicles}
        bodies |= {o.id: (o.state(t), o.radius_m, o.cooperative) for o in self.objects if o.exists(t)}
        names = list(bodies)
        states = [s for s, _, _ in bodies.values()]
        speed = np.linalg.norm([s.vel_ned for s in states], axis=1)
        speed[: len(self.vehicles)] = np.maximum(speed[: len(self.vehicles)], self._cruise)
        near = relevant(
            np.array([s.pos_ned for s in states]), speed, np.array([r for _, r, _ in bodies.values()]), self.awareness
        )
        for v, idx in zip(self.vehicles, near, strict=True):
            v.threats.intruders = self.perception[v.name].update(t, {names[j]: bodies[names[j]] for j in idx})

    def _scan(self, v: Vehicle, t: float) -> None:
        """A LiDAR sweep cast from the true pose, handed on placed with the ESTIMATED pose."""
        lidar, truth = self.lidars[v.name]
        for ret in lidar.poll(truth.sample(v.plant.truth())):
            v.threats.lidar = ret.to_scan(v.estimate)

    def _lonlat(self, coords) -> list[list[float]]:
        lat, lon, _ = ned_to_geodetic([(n, e, 0.0) for n, e in coords], self.origin)
        return [[x, y] for x, y in zip(lon.tolist(), lat.tolist(), strict=False)]

    def _log_separation(self, t: float) -> None:
        """True separation of every pair of vehicles on ``/separation/<a>/<b>`` (for plots)."""
        pos = [v.plant.truth().pos_ned for v in self.vehicles]
        for (i, a), (j, b) in itertools.combinations(enumerate(self.vehicles), 2):
            rel = pos[i] - pos[j]
            h = math.hypot(rel[0], rel[1])
            self.log.write_json(
                f"/separation/{a.name}/{b.name}",
                t,
                {"t": t, "distance_m": math.hypot(h, rel[2]), "horizontal_m": h, "vertical_m": abs(rel[2])},
                S.SEPARATION,
            )

    def _log_objects(self, t: float) -> None:
        """Objects' true positions: JSON for metrics, spheres for the 3D panel."""
        live = [o for o in self.objects if o.exists(t)]
        self.log.write_json(
            "/world/objects",
            t,
            {
                "t": t,
                "objects": [
                    {"id": o.id, "pos_ned": o.position(t), "vel_ned": o.v, "radius_m": o.radius_m} for o in live
                ],
            },
            S.OBJECTS,
            {"frame": "local-level NED from the scenario origin"},
        )
        scene = SceneUpdate()
        for o in live:
            ent = scene.entities.add(frame_id=NED_FRAME, id=o.id)
            ent.timestamp.FromNanoseconds(self.log.epoch_ns + round(t * 1e9))
            sph = ent.spheres.add()
            sph.pose.position.x, sph.pose.position.y, sph.pose.position.z = o.position(t).tolist()
            sph.pose.orientation.w = 1.0
            sph.size.x = sph.size.y = sph.size.z = 2.0 * o.radius_m
            sph.color.r, sph.color.g, sph.color.b, sph.color.a = 0.9, 0.5, 0.1, 0.6
        self.log.write_proto("/world/objects/scene", t, scene)


def _geojson(text: str):
    from foxglove_schemas_protobuf.GeoJSON_pb2 import GeoJSON

    return GeoJSON(geojson=text)
