"""Fixed-width log topics as numeric rows: the simulation appends one row of floats per log tick
and hands the writer process a block of rows at a time (:class:`sim.mcap_log.RowBuffer`); the
writer turns each row into its messages. A compact log's per-tick records cost the simulation a
list of floats instead of a message dict, its pickling and a protobuf message each.

A layout (:data:`LAYOUTS`) names a row's columns and the messages one row becomes, one channel
each: the ``truth`` row gives ``cosim.VehicleState``, ``foxglove.LocationFix`` and a
``foxglove.FrameTransforms`` (``ned`` -> vehicle) on three channels. Columns: ``(field, width)``,
width 0 a scalar, n a list of n floats, :data:`MAP` a ``map<string, double>`` whose keys the
row buffer carries once (its ``static``: ``((field, keys), ...)``, and ``("frame", name)``, the
vehicle's frame for the Foxglove messages). A dotted field is a field of a nested message (``bias.accel``). Each
message is the one :mod:`sim.log_proto` encodes from the dict the row stands for, so a log
reads back the same whichever way it was written. Units and frames: :mod:`sim.log_schemas`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.LocationFix_pb2 import LocationFix
from google.protobuf.message import Message
from mcap_protobuf.schema import build_file_descriptor_set

from sim import log_proto
from sim.core.frames import euler_to_quat

MAP = -1  # column width of a map<string, double>: its keys are in the buffer's static part
NED_FRAME = "ned"
Columns = tuple[tuple[str, int], ...]
# a message of one row: (row values, log time [ns], static) -> bytes
Build = Callable[[list[float], int, Any], bytes]


@dataclass(frozen=True)
class Output:
    """One message a row becomes: its schema (name, MCAP schema data) and its encoder."""

    schema: str
    schema_data: Callable[[], bytes]
    build: Build


@dataclass(frozen=True)
class RowLayout:
    name: str
    columns: Columns
    outputs: tuple[Output, ...]


STATE: Columns = (
    ("t", 0),
    ("pos_ned", 3),
    ("vel_ned", 3),
    ("euler", 3),
    ("rates_body", 3),
    ("alt_msl_m", 0),
    ("lat_deg", 0),
    ("lon_deg", 0),
    ("tas_mps", 0),
    ("eas_mps", 0),
    ("alpha_rad", 0),
    ("beta_rad", 0),
)


def _offsets(columns: Columns) -> dict[str, int]:
    """Each column's first index in a row (maps excluded: their width varies)."""
    out, k = {}, 0
    for name, width in columns:
        out[name] = k
        k += max(width, 1)
    return out


_AT = _offsets(STATE)


def _kinds(title: str) -> dict[str, type]:
    """Integer and boolean fields of a cosim message (dotted for nested messages); the rest are
    floats."""
    out: dict[str, type] = {}
    for name, ftype, _ in log_proto.MESSAGES[title.removeprefix(f"{log_proto.PACKAGE}.")]:
        if ftype == log_proto.INT:
            out[name] = int
        elif ftype == log_proto.B:
            out[name] = bool
        elif isinstance(ftype, str) and ftype != log_proto.MAP_FIELD:
            out.update({f"{name}.{k}": v for k, v in _kinds(ftype).items()})
    return out


def row_dict(columns: Columns, values: Sequence[float], static: Any, kinds: dict[str, type]) -> dict[str, Any]:
    """The message dict a row stands for (``static``: the buffer's ``((field, keys), ...)``)."""
    keys = dict(static)
    out: dict[str, Any] = {}
    k = 0
    for name, width in columns:
        if width == MAP:
            n = len(keys[name])
            value: Any = dict(zip(keys[name], values[k : k + n], strict=True))
        elif width:
            n, value = width, list(values[k : k + width])
        else:
            n, value = 1, values[k]
            kind = kinds.get(name)
            if kind is not None:
                value = kind(value)
        k += n
        head, _, tail = name.partition(".")
        if tail:
            out.setdefault(head, {})[tail] = value
        else:
            out[name] = value
    return out


def flatten(columns: Columns, d: dict[str, Any]) -> tuple[list[float], tuple[tuple[str, tuple[str, ...]], ...]]:
    """A message dict as a row and its static part (the keys of its maps); the inverse of
    :func:`row_dict`."""
    row: list[float] = []
    static: list[tuple[str, tuple[str, ...]]] = []
    for name, width in columns:
        head, _, tail = name.partition(".")
        v = d[head][tail] if tail else d[name]
        if width == MAP:
            static.append((name, tuple(v)))
            row.extend(v.values())
        elif width:
            row.extend(v)
        else:
            row.append(v)
    return row, tuple(static)


def _cosim(title: str, columns: Columns) -> Output:
    kinds = _kinds(title)
    encode = log_proto.encode

    def build(values: list[float], ns: int, static: Any) -> bytes:
        return encode(title, row_dict(columns, values, static, kinds))

    return Output(title, lambda: log_proto.schema_data(title), build)


def _foxglove(cls: type[Message], build: Build) -> Output:
    return Output(cls.DESCRIPTOR.full_name, lambda: build_file_descriptor_set(cls).SerializeToString(), build)


def _frame(static: Any) -> str:
    """The vehicle's frame name, ``("frame", name)`` in a truth row's static part."""
    return dict(static)["frame"]


def _location(v: list[float], ns: int, static: Any) -> bytes:
    fix = LocationFix(
        frame_id=_frame(static), latitude=v[_AT["lat_deg"]], longitude=v[_AT["lon_deg"]], altitude=v[_AT["alt_msl_m"]]
    )
    fix.timestamp.FromNanoseconds(ns)
    return fix.SerializeToString(deterministic=True)


def _transform(v: list[float], ns: int, static: Any) -> bytes:
    """``ned`` -> vehicle: position NED [m], attitude from the Euler angles [rad]."""
    e, p = _AT["euler"], _AT["pos_ned"]
    qw, qx, qy, qz = euler_to_quat(v[e], v[e + 1], v[e + 2])
    tf = FrameTransform(parent_frame_id=NED_FRAME, child_frame_id=_frame(static))
    tf.timestamp.FromNanoseconds(ns)
    tf.translation.x, tf.translation.y, tf.translation.z = v[p], v[p + 1], v[p + 2]
    r = tf.rotation
    r.x, r.y, r.z, r.w = qx, qy, qz, qw
    return FrameTransforms(transforms=[tf]).SerializeToString(deterministic=True)


SIGMA: Columns = (
    ("t", 0),
    ("pos", 3),
    ("vel", 3),
    ("att", 3),
    ("heading", 1),
    ("accel", 3),
    ("gyro", 3),
    ("baro", 1),
    ("bias.accel", 3),
    ("bias.gyro", 3),
    ("bias.baro", 1),
    ("bias.gnss_gm", 3),
)
FIXED_WING_SETPOINT: Columns = (
    ("t", 0),
    ("roll_rad", 0),
    ("altitude_m", 0),
    ("tas_mps", 0),
    ("leg", 0),
    ("cross_track_m", 0),
    ("turning", 0),
)
MULTIROTOR_SETPOINT: Columns = (
    ("t", 0),
    ("pos_ned", 3),
    ("vel_ned", 3),
    ("yaw_rad", 0),
    ("altitude_m", 0),
    ("leg", 0),
    ("cross_track_m", 0),
    ("turning", 0),
)
COMMANDS: Columns = (("t", 0), ("properties", MAP), ("debug", MAP))
TRACKING: Columns = (("t", 0), ("cross_track_m", 0), ("leg", 0))
ENERGY: Columns = (
    *((f, 0) for f in ("t", "state_of_charge", "energy_wh", "solar_w", "propulsion_w", "loads_w", "total_w")),
    *((f, 0) for f in ("battery_w", "loss_w", "curtailed_w", "shortfall_w", "sun_elevation_deg", "incidence_cos")),
    ("depleted", 0),
    ("cumulative_wh", MAP),
)


# cosim.Sensors: the row is ``t`` then each sensor's records, flat; how many records of which
# sensor is the buffer's static ``(("counts", ((sensor, n), ...)),)``
SENSOR_RECORDS: dict[str, Columns] = {
    "imu": (("t", 0), ("dt", 0), ("accel_body", 3), ("gyro_body", 3)),
    "gnss": (("t", 0), ("pos_ned", 3), ("vel_ned", 3)),
    "baro": (("t", 0), ("pressure_pa", 0)),
    "airspeed": (("t", 0), ("diff_pressure_pa", 0)),
    "mag": (("t", 0), ("field_body_ut", 3)),
}
_RECORD_WIDTH = {name: sum(max(w, 1) for _, w in cols) for name, cols in SENSOR_RECORDS.items()}


def _sensors(values: list[float], ns: int, static: Any) -> bytes:
    d: dict[str, Any] = {"t": values[0]}
    k = 1
    for name, n in dict(static)["counts"]:
        cols, w = SENSOR_RECORDS[name], _RECORD_WIDTH[name]
        d[name] = [row_dict(cols, values[k + i * w : k + (i + 1) * w], (), {}) for i in range(n)]
        k += n * w
    return log_proto.encode("cosim.Sensors", d)


def _layouts() -> dict[str, RowLayout]:
    state = _cosim("cosim.VehicleState", STATE)
    one = {
        "estimate": (STATE, "cosim.VehicleState"),
        "tracking": (TRACKING, "cosim.Tracking"),
        "sigma": (SIGMA, "cosim.EstimateSigma"),
        "fixed_wing_setpoint": (FIXED_WING_SETPOINT, "cosim.FixedWingSetpoint"),
        "multirotor_setpoint": (MULTIROTOR_SETPOINT, "cosim.MultirotorSetpoint"),
        "commands": (COMMANDS, "cosim.Commands"),
        "energy": (ENERGY, "cosim.Energy"),
    }
    out = {
        "truth": RowLayout(
            "truth", STATE, (state, _foxglove(LocationFix, _location), _foxglove(FrameTransforms, _transform))
        )
    }
    out.update({name: RowLayout(name, cols, (_cosim(title, cols),)) for name, (cols, title) in one.items()})
    sensors = Output("cosim.Sensors", lambda: log_proto.schema_data("cosim.Sensors"), _sensors)
    out["sensors"] = RowLayout("sensors", (("t", 0),), (sensors,))
    return out


LAYOUTS: dict[str, RowLayout] = _layouts()
SETPOINT_LAYOUTS = {"cosim.FixedWingSetpoint": "fixed_wing_setpoint", "cosim.MultirotorSetpoint": "multirotor_setpoint"}
