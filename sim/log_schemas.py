"""JSON Schemas of this project's own MCAP messages (Foxglove shows their fields by name).

Foxglove's well-known types (LocationFix, PoseInFrame, FrameTransforms, Log...) come from the
``foxglove-schemas-protobuf`` package instead. Units and frames are in each field's description.
The high-rate messages are written in protobuf with the same fields (:mod:`sim.log_proto`);
``cosim.LidarScan`` is protobuf only.
"""

from __future__ import annotations

_NUM = {"type": "number"}
_VEC3 = {"type": "array", "items": _NUM, "minItems": 3, "maxItems": 3}
_NUM_OR_NULL = {"type": ["number", "null"]}  # null where the field says what it means
_VEC3_OR_NULL = {"type": "array", "items": _NUM_OR_NULL, "minItems": 3, "maxItems": 3}


def _obj(title: str, fields: dict[str, tuple[dict, str]], extra: bool = False) -> dict:
    return {
        "title": title,
        "type": "object",
        "properties": {k: {**t, "description": d} for k, (t, d) in fields.items()},
        "additionalProperties": extra,
    }


VEHICLE_STATE = _obj(
    "cosim.VehicleState",
    {
        "t": (_NUM, "sim time [s]"),
        "pos_ned": (_VEC3, "local-level NED position from the scenario origin [m]"),
        "vel_ned": (_VEC3, "NED ground velocity [m/s]"),
        "euler": (_VEC3, "roll, pitch, yaw (3-2-1, body FRD to NED) [rad]"),
        "rates_body": (_VEC3, "body rates p, q, r (FRD) [rad/s]"),
        "alt_msl_m": (_NUM, "altitude above mean sea level (WGS84 ellipsoid) [m]"),
        "lat_deg": (_NUM, "geodetic latitude [deg]"),
        "lon_deg": (_NUM, "longitude [deg]"),
        "tas_mps": (_NUM, "true airspeed [m/s]"),
        "eas_mps": (_NUM, "equivalent airspeed [m/s]"),
        "alpha_rad": (_NUM, "angle of attack [rad]"),
        "beta_rad": (_NUM, "sideslip angle [rad]"),
    },
)

FIXED_WING_SETPOINT = _obj(
    "cosim.FixedWingSetpoint",
    {
        "t": (_NUM, "sim time [s]"),
        "roll_rad": (_NUM, "bank angle demand [rad]"),
        "altitude_m": (_NUM, "altitude demand, MSL [m]"),
        "tas_mps": (_NUM, "true airspeed demand [m/s]"),
        "leg": ({"type": "integer"}, "index of the plan leg being followed"),
        "cross_track_m": (_NUM, "signed cross-track error to the leg, right positive [m]"),
        "turning": ({"type": "boolean"}, "true while capturing a new leg (not straight flight)"),
    },
)

MULTIROTOR_SETPOINT = _obj(
    "cosim.MultirotorSetpoint",
    {
        "t": (_NUM, "sim time [s]"),
        "pos_ned": (
            _VEC3_OR_NULL,
            "position demand (the carrot), local-level NED [m]; null on an axis: velocity control on it",
        ),
        "vel_ned": (_VEC3, "velocity feed-forward NED [m/s]"),
        "yaw_rad": (_NUM_OR_NULL, "yaw demand [rad]; null: hold the heading"),
        "altitude_m": (_NUM_OR_NULL, "altitude demand, MSL [m]; null: vertical velocity control"),
        "leg": ({"type": "integer"}, "index of the plan leg being followed"),
        "cross_track_m": (_NUM, "distance from the leg line (3-D) [m]"),
        "turning": ({"type": "boolean"}, "true while the carrot waits (vertex, hold, landing)"),
    },
)

TRACKING = _obj(
    "cosim.Tracking",
    {
        "t": (_NUM, "sim time [s]"),
        "cross_track_m": (
            _NUM,
            "TRUE cross-track error to the leg being followed [m] (fixed wing: signed, "
            "horizontal, right positive; multirotor: 3-D distance)",
        ),
        "leg": ({"type": "integer"}, "index of the plan leg being followed"),
    },
)

COMMANDS = _obj(
    "cosim.Commands",
    {
        "t": (_NUM, "sim time [s]"),
        "properties": (
            {"type": "object", "additionalProperties": _NUM},
            "JSBSim property commands written this tick (JSBSim units)",
        ),
        "debug": (
            {"type": "object", "additionalProperties": _NUM},
            "controller internals (energy errors, integrators...)",
        ),
    },
)

PLAN = _obj(
    "cosim.Plan",
    {
        "t": (_NUM, "sim time the plan was made [s]"),
        "planner": ({"type": "string"}, "planner name"),
        "status": ({"type": "string", "enum": ["ok", "degraded", "no_solution"]}, "plan status"),
        "positions": ({"type": "array", "items": _VEC3}, "vertices, local-level NED [m]"),
        "times": ({"type": "array", "items": _NUM}, "sim time each vertex is due [s]"),
        "labels": ({"type": "array", "items": {"type": "integer"}}, "mission waypoint index or -1"),
        "diagnostics": ({"type": "object"}, "planner-specific values"),
        "turn_rates": (
            {"type": "array", "items": _NUM},
            "planned air-relative course rate on the leg from each vertex [rad/s], + right (turn-model plans only)",
        ),
        "airspeeds": (
            {"type": "array", "items": _NUM},
            "commanded true airspeed on the leg from each vertex [m/s] (plans that command one, e.g. a hold at V_cor)",
        ),
    },
)

WALL_TIMING = _obj(
    "cosim.WallTiming",
    {
        "t": (_NUM, "sim time [s]"),
        "seconds": (_NUM, "wall-clock time the call took [s]; differs run to run by nature"),
    },
)

THREATS = _obj(
    "cosim.Threats",
    {
        "t": (_NUM, "sim time the planner saw these threats [s]"),
        "intruders": (
            {"type": "array", "items": {"type": "object"}},
            "tracked intruders: id, t, pos_ned [m], vel_ned [m/s], radius_m, pos_cov, vel_cov, cooperative",
        ),
        "spheres": (
            {"type": "array", "items": {"type": "object"}},
            "spherical threats: id, t, center_ned [m], radius_m, vel_ned [m/s], center_cov",
        ),
        "storms": (
            {"type": "array", "items": {"type": "object"}},
            "storm nowcast snapshots: t [s], cells = polygons [[north, east], ...] [m], "
            "velocities_ne = cell velocities [[north, east], ...] [m/s] or null, "
            "extents_up_m = cell heights above the origin [[base, top], ...] [m] (null where unbounded) "
            "or null",
        ),
        "lidar_hits": ({"type": "integer"}, "returns in the latest LiDAR scan"),
        "lidar": (
            {"type": ["object", "null"]},
            "latest LiDAR scan: t [s], origin_ned [m], directions_ned (unit, NED), ranges_m [m], hit, max_range_m; "
            "absent in a compact log, whose scan is on /<v>/threats/lidar (cosim.LidarScan) at the same log time",
        ),
    },
)

PLAN_INPUT = _obj(
    "cosim.PlanInput",
    {
        "t": (_NUM, "sim time of the planner call [s]"),
        "planner": ({"type": "string"}, "planner name"),
        "estimate": (
            {"type": "object"},
            "the estimate the planner saw (cosim.VehicleState; with pos_sigma_m, the 1-sigma N, E, D"
            " position uncertainty [m], from an estimator that has one)",
        ),
        "mission": (
            {"type": "object"},
            "mission progress: reached = [[waypoint index, sim time [s]], ...], landed_t, completed_t [s] or null",
        ),
        "new_plan": ({"type": "boolean"}, "the call made a new plan (false: the planner kept its plan)"),
        "mission_setup": (
            {"type": "object"},
            "only when the planner was built since the previous call: the mission it was built for "
            "(waypoints NED [m], cruise_speed [m/s], acceptance_radius [m], start NED [m] or null, "
            "hold_s = [[waypoint index, s], ...], land)",
        ),
        "mode_setup": (
            {"type": "object"},
            "only with mission_setup, for a ground-station mode planner: what it was built from "
            "(hold: position NED [m]; goto: start and target NED [m], speed [m/s])",
        ),
    },
)

PLAN_OBSERVATION = _obj(
    "cosim.PlanObservation",
    {
        "t": (_NUM, "sim time of the observation [s]"),
        "estimate": (
            {"type": "object"},
            "the estimate an observing planner sampled between its calls (cosim.VehicleState, as in cosim.PlanInput)",
        ),
    },
)

_RECORDS = {"type": "array", "items": {"type": "object"}}
SENSORS = _obj(
    "cosim.Sensors",
    {
        "t": (_NUM, "sim time of the log tick [s]"),
        "imu": (_RECORDS, "per fusion interval: t, dt [s], accel_body [m/s^2], gyro_body [rad/s] (FRD, mean)"),
        "gnss": (_RECORDS, "fixes: t (validity) [s], pos_ned [m], vel_ned [m/s]"),
        "baro": (_RECORDS, "t [s], pressure_pa"),
        "airspeed": (_RECORDS, "t [s], diff_pressure_pa"),
        "mag": (_RECORDS, "t [s], field_body_ut"),
    },
    extra=True,
)

ESTIMATE_SIGMA = _obj(
    "cosim.EstimateSigma",
    {
        "t": (_NUM, "sim time [s]"),
        "pos": (_VEC3, "3-sigma position NED [m]"),
        "vel": (_VEC3, "3-sigma velocity NED [m/s]"),
        "att": (_VEC3, "3-sigma attitude error, body axes [rad]"),
        "heading": ({"type": "array", "items": _NUM}, "3-sigma heading [rad]"),
        "accel": (_VEC3, "3-sigma accel bias [m/s^2]"),
        "gyro": (_VEC3, "3-sigma gyro bias [rad/s]"),
        "baro": ({"type": "array", "items": _NUM}, "3-sigma baro height bias [m]"),
        "bias": ({"type": "object"}, "estimated biases: accel [m/s^2], gyro [rad/s], baro [m], gnss_gm [m]"),
    },
)

OBJECTS = _obj(
    "cosim.Objects",
    {
        "t": (_NUM, "sim time [s]"),
        "objects": (
            {"type": "array", "items": {"type": "object"}},
            "scripted traffic: id, pos_ned [m], vel_ned [m/s], radius_m (true)",
        ),
    },
)

SEPARATION = _obj(
    "cosim.Separation",
    {
        "t": (_NUM, "sim time [s]"),
        "distance_m": (_NUM, "true 3-D distance between the two vehicles [m]"),
        "horizontal_m": (_NUM, "true horizontal distance [m]"),
        "vertical_m": (_NUM, "true vertical distance (absolute) [m]"),
    },
)

MISSION_STATUS = _obj(
    "cosim.MissionStatus",
    {
        "t": (_NUM, "sim time [s]"),
        "next_waypoint": ({"type": "integer"}, "index of the waypoint being flown to"),
        "waypoints": ({"type": "integer"}, "number of waypoints"),
        "complete": ({"type": "boolean"}, "all waypoints reached"),
    },
)

ENERGY = _obj(
    "cosim.Energy",
    {
        "t": (_NUM, "sim time at the end of the energy step [s]"),
        "state_of_charge": (_NUM, "battery state of charge, usable energy / usable capacity [0..1]"),
        "energy_wh": (_NUM, "usable energy stored [Wh]"),
        "solar_w": (_NUM, "solar-array electrical power after the MPPT [W]"),
        "propulsion_w": (_NUM, "motors' electrical power, shaft power / motor efficiency [W]"),
        "loads_w": (_NUM, "avionics + payload [W]"),
        "total_w": (_NUM, "bus power solar - propulsion - loads, > 0 charging [W]"),
        "battery_w": (_NUM, "power into the cells after conversion losses, < 0 discharging [W]"),
        "loss_w": (_NUM, "charge/discharge conversion loss [W]"),
        "curtailed_w": (_NUM, "solar power not taken (battery full or charge limit) [W]"),
        "shortfall_w": (_NUM, "demand not delivered (battery empty or discharge limit) [W]"),
        "sun_elevation_deg": (_NUM, "apparent sun elevation at the vehicle [deg]"),
        "incidence_cos": (_NUM, "cosine of the sun's incidence on the array (0: behind it)"),
        "depleted": ({"type": "boolean"}, "the battery ran empty; the motors are stopped"),
        "cumulative_wh": (
            {"type": "object", "additionalProperties": _NUM},
            "energies since the start [Wh]: solar, propulsion, loads, loss, curtailed, shortfall",
        ),
    },
)

LIDAR_SCAN = _obj(
    "cosim.LidarScan",
    {
        "t": (_NUM, "sim time of the sweep [s]"),
        "origin_ned": (_VEC3, "sensor position, local-level NED (estimated) [m]"),
        "rotation": (
            {"type": "array", "items": _NUM, "minItems": 9, "maxItems": 9},
            "sensor -> NED rotation matrix, row-major: directions_ned = pattern directions @ rotation.T",
        ),
        "azimuth_min_deg": (_NUM, "scan pattern: first azimuth, from the sensor x axis, right positive [deg]"),
        "azimuth_max_deg": (_NUM, "scan pattern: last azimuth (a full turn does not repeat it) [deg]"),
        "azimuth_step_deg": (_NUM, "scan pattern: azimuth step [deg]"),
        "elevation_min_deg": (_NUM, "scan pattern: lowest elevation, up positive [deg]"),
        "elevation_max_deg": (_NUM, "scan pattern: highest elevation [deg]"),
        "elevation_step_deg": (_NUM, "scan pattern: elevation step [deg]"),
        "max_range_m": (_NUM, "sensor range; the range of a ray without a return [m]"),
        "range_resolution_m": (_NUM, "range step: every return is a whole number of steps [m]"),
        "rays": ({"type": "integer"}, "rays in the pattern (elevation-major)"),
        "hit": ({}, "bytes: a bit per ray in pattern order, set where it returned (little bit order)"),
        "hit_range_steps": (
            {"type": "array", "items": {"type": "integer"}},
            "the returns' ranges in range steps, each as the difference to the previous return's",
        ),
    },
)

CRASH = _obj(
    "cosim.Crash",
    {
        "t": (_NUM, "sim time of the contact [s]"),
        "vehicle": ({"type": "string"}, "the vehicle that crashed"),
        "kind": (
            {"enum": ["ground", "obstacle", "vehicle", "object"]},
            "what it hit: the ground, an obstacle, another vehicle or a traffic object",
        ),
        "hit": ({"type": "string"}, "\"ground\", the obstacle's id, the other vehicle's name or the object's id"),
        "impact_speed_mps": (_NUM, "speed relative to what it hit [m/s] (ground: just before first contact)"),
        "pos_ned": (_VEC3, "true position at the contact, local-level NED from the scenario origin [m]"),
    },
)

# -- the central UTM authority (sim/utm_authority.py); GCF = ENU [m] from the scenario origin ----
_CASES = {"type": "array", "items": {"type": "object"}}
_CLUSTER = ({"type": "string"}, "the authority's airspace cluster (utm.cluster id; all: one authority)")
_CASE_FIELDS = (
    "collision case records: t, ids, encounter, alpha_deg, roles, collision_point_enu [m], distance_m, "
    "t_cpa_s, margin_m, flagged, trajectory, head_t, separation_m"
)

UTM_NOTIFICATION = _obj(
    "cosim.UtmNotification",
    {
        "cluster": _CLUSTER,
        "t": (_NUM, "sim time the authority received it [s]"),
        "sent_t": (_NUM, "sim time the vehicle sent it (its UTM frame) [s]"),
        "from": ({"type": "string"}, "the notifying vehicle"),
        "pos_enu": (_VEC3, "estimated position, GCF ENU [m]"),
        "vel_enu": (_VEC3, "estimated velocity, GCF ENU [m/s]"),
        "plan_enu": ({"type": "array", "items": _VEC3}, "filed mission plan, one point per UTM frame from sent_t [m]"),
    },
)

UTM_FRAME = _obj(
    "cosim.UtmFrame",
    {
        "cluster": _CLUSTER,
        "t": (_NUM, "frame start, sim time [s]"),
        "frame": ({"type": "integer"}, "UTM frame index"),
        "notified": ({"type": "array", "items": {"type": "string"}}, "vehicles with a fresh notification"),
        "opened": (_CASES, "cases opened this frame: " + _CASE_FIELDS),
        "closed": (_CASES, "cases closed this frame"),
        "active": (_CASES, "active (head-chained) cases"),
        "roundabouts": (_CASES, "virtual roundabouts: members, centre_enu [m], margin_m"),
        "unacknowledged": (
            {"type": "array", "items": {"type": "string"}},
            "directed vehicles without an acknowledgement within lost_after",
        ),
    },
)

UTM_DIRECTIVE = _obj(
    "cosim.UtmDirective",
    {
        "cluster": _CLUSTER,
        "t": (_NUM, "sim time sent (frame start) [s]"),
        "frame": ({"type": "integer"}, "UTM frame index"),
        "to": ({"type": "string"}, "the recipient"),
        "received_t": (
            _NUM_OR_NULL,
            "sim time the recipient gets it (the first authority tick at or after its arrival) [s]; null: lost",
        ),
        "cases": (_CASES, "the recipient's active cases (roundabout members re-targeted): " + _CASE_FIELDS),
        "weather": (
            _CASES,
            "weather cases of the cells its filed route crosses (utm.weather): id, t, centre_enu [m], margin_m, "
            "velocity_enu [m/s], moving, body_enu [m]",
        ),
        "mandates": (
            _CASES,
            "mandates in force for the recipient (never broken): id, kind (keep_clear), start_t, end_t [s], "
            "centre_enu (east, north) [m], radius_m, up_min_m, up_max_m (heights above the origin, null: unbounded)",
        ),
    },
)

UTM_ACK = _obj(
    "cosim.UtmAck",
    {
        "cluster": _CLUSTER,
        "t": (_NUM, "sim time the authority received it [s]"),
        "from": ({"type": "string"}, "the acknowledging vehicle"),
        "frame": ({"type": "integer"}, "the acknowledged directive's frame"),
        "mandates": ({"type": "array", "items": {"type": "string"}}, "ids of the mandates the vehicle obeys"),
    },
    extra=True,
)

UTM_LINK = _obj(
    "cosim.UtmLink",
    {
        "cluster": _CLUSTER,
        "t": (_NUM, "sim time [s]"),
        "vehicle": ({"type": "string"}, "the vehicle"),
        "state": (
            {"enum": ["lost", "up", "left"]},
            "the authority's view: lost = no notification within lost_after, left = notified outside the cluster's "
            "handover band",
        ),
    },
)

UTM_BREACH = _obj(
    "cosim.UtmBreach",
    {
        "cluster": _CLUSTER,
        "t": (_NUM, "sim time [s]"),
        "case": ({"type": "object"}, "the breached case (separation_m < margin_m)"),
        "vehicle": ({"type": "string"}, "the vehicle notified inside a mandate's cylinder"),
        "mandate": ({"type": "object"}, "the breached mandate (as in /utm/directive)"),
    },
)


def _peer(title: str, what: str, fields: dict[str, tuple[dict, str]]) -> dict:
    """A vehicle-to-vehicle message (sim/peer_link.py), logged when sent."""
    return _obj(
        title,
        {
            "t": (_NUM, "sim time sent [s]"),
            "from": ({"type": "string"}, "the sender"),
            "to": ({"type": "string"}, "the recipient"),
            "received_t": (
                _NUM_OR_NULL,
                "sim time the recipient gets it (the first tick at or after arrival) [s]; null: lost",
            ),
            **fields,
        },
    ) | {"description": what}


UTM_PEER_NOTIFICATION = _peer(
    "cosim.UtmPeerNotification",
    "position notification broadcast to a peer",
    {"pos_enu": (_VEC3, "estimated position, GCF ENU [m]"), "vel_enu": (_VEC3, "estimated velocity, GCF ENU [m/s]")},
)
UTM_PEER_CLAIM = _peer(
    "cosim.UtmPeerClaim",
    "response mode: the separation mode (collision case) the sender claims for the pair",
    {"case": ({"type": "object"}, "the claimed case, registration ids: " + _CASE_FIELDS)},
)
UTM_PEER_ACK = _peer(
    "cosim.UtmPeerAck",
    "response mode: the acknowledgement of a peer's claim",
    {"case": ({"type": "object"}, "the acknowledged claim's case, registration ids")},
)

UTM_SPOOF = _obj(
    "cosim.UtmSpoof",
    {
        "cluster": _CLUSTER,
        "t": (_NUM, "sim time injected [s]"),
        "to": ({"type": "string"}, "the vehicle whose downlink carries the forged case"),
        "case": ({"type": "object"}, "the forged case"),
    },
)
