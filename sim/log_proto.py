"""Protobuf schemas of the high-rate log topics, built at import from the field tables below with
``descriptor_pb2`` (no generated code to drift), and the message <-> dict conversion.

Each message mirrors the JSON Schema of the same title in :mod:`sim.log_schemas` field for field
(names, units, frames there), so a protobuf message decodes to the dict the JSON message would
have given: every field present, NaN and infinities as ``None`` (JSON has no NaN), an empty
measurement list of ``cosim.Sensors`` omitted (the JSON message leaves out a sensor that
delivered nothing). Precision: every float is a ``double`` (read back bit-identical: live and
replayed metrics stay equal, a re-run planner sees what the live one saw) except the measured
values of ``cosim.Sensors`` (float32: no metric or re-run reads them, and float32 resolves far
below each sensor's noise); the LiDAR scan is compact (``cosim.LidarScan`` below).

MCAP profile: schema encoding ``protobuf`` with a FileDescriptorSet (:func:`schema_data`),
message encoding ``protobuf``: Foxglove shows the fields by name.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from google.protobuf.descriptor import Descriptor, FieldDescriptor
from google.protobuf.message import Message

from sim.core.threats import LidarScan, ScanPattern

PACKAGE = "cosim"
FILE_NAME = "cosim/log.proto"

_F = descriptor_pb2.FieldDescriptorProto
D, F32, INT, B = _F.TYPE_DOUBLE, _F.TYPE_FLOAT, _F.TYPE_SINT64, _F.TYPE_BOOL
S, BYTES = _F.TYPE_STRING, _F.TYPE_BYTES
MAP_FIELD = "map"  # a map<string, double>

# message -> [(field, scalar type or message name or MAP_FIELD, repeated)]; field numbers in order
_VEC = True
MESSAGES: dict[str, list[tuple[str, Any, bool]]] = {
    "VehicleState": [
        ("t", D, False),
        ("pos_ned", D, _VEC),
        ("vel_ned", D, _VEC),
        ("euler", D, _VEC),
        ("rates_body", D, _VEC),
        ("alt_msl_m", D, False),
        ("lat_deg", D, False),
        ("lon_deg", D, False),
        ("tas_mps", D, False),
        ("eas_mps", D, False),
        ("alpha_rad", D, False),
        ("beta_rad", D, False),
    ],
    "Tracking": [("t", D, False), ("cross_track_m", D, False), ("leg", INT, False)],
    "FixedWingSetpoint": [
        ("t", D, False),
        ("roll_rad", D, False),
        ("altitude_m", D, False),
        ("tas_mps", D, False),
        ("leg", INT, False),
        ("cross_track_m", D, False),
        ("turning", B, False),
    ],
    "MultirotorSetpoint": [
        ("t", D, False),
        ("pos_ned", D, _VEC),
        ("vel_ned", D, _VEC),
        ("yaw_rad", D, False),
        ("altitude_m", D, False),
        ("leg", INT, False),
        ("cross_track_m", D, False),
        ("turning", B, False),
    ],
    "Commands": [("t", D, False), ("properties", MAP_FIELD, False), ("debug", MAP_FIELD, False)],
    # measured values in float32 (relative resolution 6e-8, far below every sensor's noise: 1 mm
    # of GNSS position at 20 km, 0.008 Pa of 1e5 Pa); their times in double
    "ImuRecord": [("t", D, False), ("dt", D, False), ("accel_body", F32, _VEC), ("gyro_body", F32, _VEC)],
    "GnssRecord": [("t", D, False), ("pos_ned", F32, _VEC), ("vel_ned", F32, _VEC)],
    "BaroRecord": [("t", D, False), ("pressure_pa", F32, False)],
    "AirspeedRecord": [("t", D, False), ("diff_pressure_pa", F32, False)],
    "MagRecord": [("t", D, False), ("field_body_ut", F32, _VEC)],
    "Sensors": [
        ("t", D, False),
        ("imu", "ImuRecord", _VEC),
        ("gnss", "GnssRecord", _VEC),
        ("baro", "BaroRecord", _VEC),
        ("airspeed", "AirspeedRecord", _VEC),
        ("mag", "MagRecord", _VEC),
    ],
    "EstimateBias": [("accel", D, _VEC), ("gyro", D, _VEC), ("baro", D, _VEC), ("gnss_gm", D, _VEC)],
    "EstimateSigma": [
        ("t", D, False),
        ("pos", D, _VEC),
        ("vel", D, _VEC),
        ("att", D, _VEC),
        ("heading", D, _VEC),
        ("accel", D, _VEC),
        ("gyro", D, _VEC),
        ("baro", D, _VEC),
        ("bias", "EstimateBias", False),
    ],
    "Energy": [
        ("t", D, False),
        ("state_of_charge", D, False),
        ("energy_wh", D, False),
        ("solar_w", D, False),
        ("propulsion_w", D, False),
        ("loads_w", D, False),
        ("total_w", D, False),
        ("battery_w", D, False),
        ("loss_w", D, False),
        ("curtailed_w", D, False),
        ("shortfall_w", D, False),
        ("sun_elevation_deg", D, False),
        ("incidence_cos", D, False),
        ("depleted", B, False),
        ("cumulative_wh", MAP_FIELD, False),
    ],
    # A sweep as the sensor reports it: ray directions = pattern (sensor frame) @ rotation.T
    # (rotation: sensor -> NED DCM, row-major), ranges in whole steps of range_resolution_m
    # (the sensor's resolution, so they read back exact); hit: one bit per ray in pattern order
    # (numpy packbits, little bit order); hit_range_steps: the hits' range steps, each as the
    # difference to the previous hit's (neighbouring rays see the same surface: small varints).
    "LidarScan": [
        ("t", D, False),
        ("origin_ned", D, _VEC),
        ("rotation", D, _VEC),
        ("azimuth_min_deg", D, False),
        ("azimuth_max_deg", D, False),
        ("azimuth_step_deg", D, False),
        ("elevation_min_deg", D, False),
        ("elevation_max_deg", D, False),
        ("elevation_step_deg", D, False),
        ("max_range_m", D, False),
        ("range_resolution_m", D, False),
        ("rays", INT, False),
        ("hit", BYTES, False),
        ("hit_range_steps", INT, _VEC),
    ],
}
OMIT_EMPTY = frozenset({"Sensors"})  # messages whose empty lists the JSON message leaves out


def _file() -> descriptor_pb2.FileDescriptorProto:
    fd = descriptor_pb2.FileDescriptorProto(name=FILE_NAME, package=PACKAGE, syntax="proto3")
    for name, fields in MESSAGES.items():
        msg = fd.message_type.add(name=name)
        for number, (fname, ftype, repeated) in enumerate(fields, start=1):
            label = _F.LABEL_REPEATED if repeated or ftype == MAP_FIELD else _F.LABEL_OPTIONAL
            f = msg.field.add(name=fname, number=number, label=label, json_name=fname)
            if ftype == MAP_FIELD:
                entry = f"{''.join(p.title() for p in fname.split('_'))}Entry"
                nested = msg.nested_type.add(name=entry)
                nested.options.map_entry = True
                nested.field.add(name="key", number=1, label=_F.LABEL_OPTIONAL, type=S)
                nested.field.add(name="value", number=2, label=_F.LABEL_OPTIONAL, type=D)
                f.type, f.type_name = _F.TYPE_MESSAGE, f".{PACKAGE}.{name}.{entry}"
            elif isinstance(ftype, str):
                f.type, f.type_name = _F.TYPE_MESSAGE, f".{PACKAGE}.{ftype}"
            else:
                f.type = ftype
    return fd


FILE = _file()
_POOL = descriptor_pool.DescriptorPool()
_POOL.Add(FILE)
CLASSES: dict[str, type[Message]] = {
    f"{PACKAGE}.{n}": message_factory.GetMessageClass(_POOL.FindMessageTypeByName(f"{PACKAGE}.{n}")) for n in MESSAGES
}


def _uses(name: str) -> list[str]:
    """``name`` and the messages its fields hold, each once, dependencies first."""
    out: list[str] = []
    for _, ftype, _ in MESSAGES[name]:
        if isinstance(ftype, str) and ftype != MAP_FIELD:
            out += [m for m in _uses(ftype) if m not in out]
    return [*out, name]


def schema_data(title: str) -> bytes:
    """The MCAP schema record's data of message ``title``: a serialised FileDescriptorSet of
    one file (``cosim/<Name>.proto``) holding it and the messages it uses (a few hundred bytes,
    stored once per message type)."""
    name = title.removeprefix(f"{PACKAGE}.")
    by_name = {m.name: m for m in FILE.message_type}
    fd = descriptor_pb2.FileDescriptorProto(name=f"{PACKAGE}/{name}.proto", package=PACKAGE, syntax="proto3")
    fd.message_type.extend(by_name[m] for m in _uses(name))
    return descriptor_pb2.FileDescriptorSet(file=[fd]).SerializeToString(deterministic=True)


def encode(title: str, obj: dict[str, Any]) -> bytes:
    """``obj`` (a log message as for the JSON Schema titled ``title``; NaN where JSON would
    write null) as protobuf bytes; a missing key is the field's default, a key the message lacks
    is a ValueError."""
    try:
        return CLASSES[title](**obj).SerializeToString(deterministic=True)
    except (ValueError, TypeError) as exc:
        raise ValueError(f"{title}: {exc}") from None


def has_schema(title: str) -> bool:
    """A protobuf message of this title exists (the others stay JSON)."""
    return title in CLASSES


def _finite(x: float) -> float | None:
    return x if math.isfinite(x) else None


def _finite_map(v: Any) -> dict[str, float | None]:
    return {k: _finite(x) for k, x in v.items()}


def _finite_list(v: Any) -> list[float | None]:
    return [_finite(x) for x in v]


def _same(v: Any) -> Any:
    return v


def _field_converter(f: FieldDescriptor) -> Callable[[Any], Any]:
    """Turns a field's value into its JSON-equivalent."""
    if f.message_type is not None and f.message_type.GetOptions().map_entry:
        return _finite_map
    if f.message_type is not None:
        sub = _converter(f.message_type)
        return (lambda v: [sub(m) for m in v]) if f.is_repeated else sub
    if f.type in (FieldDescriptor.TYPE_DOUBLE, FieldDescriptor.TYPE_FLOAT):
        return _finite_list if f.is_repeated else _finite
    return list if f.is_repeated else _same


def _converter(desc: Descriptor) -> Callable[[Message], dict[str, Any]]:
    """A function turning a message of ``desc`` into its JSON-equivalent dict."""
    omit = desc.name in OMIT_EMPTY
    steps = [(f.name, _field_converter(f), omit and f.is_repeated) for f in desc.fields]

    def convert(msg: Message) -> dict[str, Any]:
        out = {}
        for name, fn, skip_empty in steps:
            v = getattr(msg, name)
            if skip_empty and not v:
                continue
            out[name] = fn(v)
        return out

    return convert


_CONVERTERS: dict[Descriptor, Callable[[Message], dict[str, Any]]] = {}  # per descriptor: per file read


def record_dict(msg: Message) -> dict[str, Any]:
    """A decoded cosim message as the dict of its fields, as its JSON message would give."""
    desc = msg.DESCRIPTOR
    conv = _CONVERTERS.get(desc)
    if conv is None:
        conv = _CONVERTERS[desc] = _converter(desc)
    return conv(msg)


def to_dict(msg: Message) -> dict[str, Any]:
    """A decoded cosim message as its reader's dict: :func:`record_dict`, and for
    ``cosim.LidarScan`` the scan's arrays (:func:`scan_dict`)."""
    d = record_dict(msg)
    return scan_dict(d) if msg.DESCRIPTOR.full_name == f"{PACKAGE}.LidarScan" else d


# -- the LiDAR scan --------------------------------------------------------------------------
_PATTERN_FIELDS = (
    "azimuth_min_deg",
    "azimuth_max_deg",
    "azimuth_step_deg",
    "elevation_min_deg",
    "elevation_max_deg",
    "elevation_step_deg",
)


def scan_record(scan: LidarScan) -> dict[str, Any]:
    """A scan as the ``cosim.LidarScan`` message (dict); ValueError for a scan without its
    pattern, rotation or range resolution (a scan not made by :mod:`sim.sensors.lidar`)."""
    if scan.pattern is None or scan.rotation is None or scan.range_resolution_m is None:
        raise ValueError("a logged LiDAR scan needs its pattern, rotation and range resolution")
    hit = np.asarray(scan.hit, bool)
    steps = np.rint(np.asarray(scan.ranges_m)[hit] / scan.range_resolution_m).astype(np.int64)
    return {
        "t": scan.t,
        "origin_ned": np.asarray(scan.origin_ned, float).tolist(),
        "rotation": np.asarray(scan.rotation, float).ravel().tolist(),
        **{k: getattr(scan.pattern, k) for k in _PATTERN_FIELDS},
        "max_range_m": scan.max_range_m,
        "range_resolution_m": scan.range_resolution_m,
        "rays": len(hit),
        "hit": np.packbits(hit, bitorder="little").tobytes(),
        "hit_range_steps": np.diff(steps, prepend=0).tolist(),
    }


def scan_dict(rec: dict[str, Any]) -> dict[str, Any]:
    """A ``cosim.LidarScan`` record (:func:`scan_record`) as the scan's arrays: ``t``,
    ``origin_ned``, ``directions_ned`` (N, 3), ``ranges_m`` (N,) [m], ``hit`` (N,) bool,
    ``max_range_m`` as the JSON logs carried them, plus ``rotation`` (3, 3), ``pattern`` (the
    six angles [deg]) and ``range_resolution_m`` [m]; bit-identical to the scan logged."""
    n = int(rec["rays"])
    pattern = ScanPattern(**{k: rec[k] for k in _PATTERN_FIELDS})
    rotation = np.asarray(rec["rotation"], float).reshape(3, 3)
    hit = np.unpackbits(np.frombuffer(rec["hit"], np.uint8), count=n, bitorder="little").astype(bool)
    ranges = np.full(n, float(rec["max_range_m"]))
    ranges[hit] = np.cumsum(np.asarray(rec["hit_range_steps"], np.int64)).astype(float) * rec["range_resolution_m"]
    return {
        "t": rec["t"],
        "origin_ned": rec["origin_ned"],
        "directions_ned": pattern.directions() @ rotation.T,
        "ranges_m": ranges,
        "hit": hit,
        "max_range_m": rec["max_range_m"],
        "rotation": rotation,
        "pattern": {k: rec[k] for k in _PATTERN_FIELDS},
        "range_resolution_m": rec["range_resolution_m"],
    }
