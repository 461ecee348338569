"""Fixed-width log topics as numeric rows: the simulation appends one row of floats per log tick
and hands the writer process a block of rows at a time (:class:`sim.mcap_log.RowBuffer`); the
writer turns each row into its messages. A compact log's per-tick records cost the simulation a
list of floats instead of a message dict, its pickling and a protobuf message each.

A layout (:data:`LAYOUTS`) names a row's columns and the messages one row becomes, one channel
each: the ``truth`` row gives ``cosim.VehicleState``, ``foxglove.LocationFix`` and a
``foxglove.FrameTransforms`` (``ned`` -> vehicle) on three channels. A row's first column is its
log time, sim [s] (the message's ``t`` too, except ``energy``: a column of its own). Columns:
``(field, width)``, width 0 a scalar, n a list of n floats, :data:`MAP` a ``map<string,
double>`` whose keys the row buffer carries once (its ``static``: ``((field, keys), ...)``, and
``("frame", name)``, the vehicle's frame for the Foxglove messages, ``("counts", ...)`` the
sensors' records per row). A dotted field is a field of a nested message (``bias.accel``). Each
message is the one :mod:`sim.log_proto` encodes from the dict the row stands for, so a log reads
back the same whichever way it was written; ``sigma`` rows carry the covariance the 3-sigma
bounds are computed from, in the writer. Units and frames: :mod:`sim.log_schemas`.
"""

from __future__ import annotations

import functools
import operator
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
from sim.estimation.ins_model import sigma_bounds

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
    for name, head, tail, width in _split(columns):
        v = d[head][tail] if tail else d[name]
        if width == MAP:
            static.append((name, tuple(v)))
            row.extend(v.values())
        elif width:
            row.extend(v)
        else:
            row.append(v)
    return row, tuple(static)


def record_values(columns: Columns) -> Callable[[dict[str, Any]], list[float]]:
    """A function giving a message dict's row as :func:`flatten` does, for columns of top-level
    scalars and lists only (no maps, no nested fields): all fields in one lookup, built once
    per layout for records made every log tick."""
    if any(width == MAP or "." in name for name, width in columns):
        raise ValueError(f"record_values: columns {columns} have a map or a nested field")
    names = tuple(name for name, _ in columns)
    get: Callable[[dict[str, Any]], tuple] = operator.itemgetter(*names) if len(names) > 1 else lambda d: (d[names[0]],)
    widths = tuple(width for _, width in columns)
    if not any(widths):
        return lambda d: list(get(d))

    def values(d: dict[str, Any]) -> list[float]:
        row: list[float] = []
        for v, width in zip(get(d), widths, strict=True):
            if width:
                row += v
            else:
                row.append(v)
        return row

    return values


@functools.cache
def _split(columns: Columns) -> list[tuple[str, str, str, int]]:
    """Per column: its name, the name's head and tail (``bias.accel``: ``bias``, ``accel``) and
    its width."""
    return [(name, *_parts(name), width) for name, width in columns]


def _parts(name: str) -> tuple[str, str]:
    head, _, tail = name.partition(".")
    return head, tail


def _cosim(title: str, columns: Columns, lead: int = 0) -> Output:
    """The message ``title`` of the row's columns after its first ``lead`` (a log time that is
    not the message's own ``t``)."""
    kinds = _kinds(title)
    encode = log_proto.encode

    def build(values: list[float], ns: int, static: Any) -> bytes:
        return encode(title, row_dict(columns, values[lead:] if lead else values, static, kinds))

    return Output(title, lambda: log_proto.schema_data(title), build)


def _foxglove(cls: type[Message], build: Build) -> Output:
    return Output(cls.DESCRIPTOR.full_name, lambda: build_file_descriptor_set(cls).SerializeToString(), build)


def _frame(static: Any) -> str:
    """The vehicle's frame name, ``("frame", name)`` in a truth row's static part."""
    return dict(static)["frame"]


def location_fix(v: Sequence[float], ns: int, frame: str) -> LocationFix:
    """The ``foxglove.LocationFix`` of a state row (:data:`STATE`) at log time ``ns``."""
    fix = LocationFix(
        frame_id=frame, latitude=v[_AT["lat_deg"]], longitude=v[_AT["lon_deg"]], altitude=v[_AT["alt_msl_m"]]
    )
    fix.timestamp.FromNanoseconds(ns)
    return fix


def ned_transforms(v: Sequence[float], ns: int, frame: str) -> FrameTransforms:
    """``ned`` -> ``frame`` of a state row (:data:`STATE`) at log time ``ns``: position NED [m],
    attitude from the Euler angles [rad]."""
    e, p = _AT["euler"], _AT["pos_ned"]
    qw, qx, qy, qz = euler_to_quat(v[e], v[e + 1], v[e + 2])
    tf = FrameTransform(parent_frame_id=NED_FRAME, child_frame_id=frame)
    tf.timestamp.FromNanoseconds(ns)
    tf.translation.x, tf.translation.y, tf.translation.z = v[p], v[p + 1], v[p + 2]
    r = tf.rotation
    r.x, r.y, r.z, r.w = qx, qy, qz, qw
    return FrameTransforms(transforms=[tf])


def _location(v: list[float], ns: int, static: Any) -> bytes:
    return location_fix(v, ns, _frame(static)).SerializeToString(deterministic=True)


def _transform(v: list[float], ns: int, static: Any) -> bytes:
    return ned_transforms(v, ns, _frame(static)).SerializeToString(deterministic=True)


# the row of cosim.EstimateSigma: what the bounds are computed from (SensorEstimator.covariance_row)
SIGMA_INPUTS: Columns = (
    ("t", 0),
    ("var", 16),
    ("q", 4),
    ("p_att", 9),
    ("bias.accel", 3),
    ("bias.gyro", 3),
    ("bias.baro", 1),
    ("bias.gnss_gm", 3),
)


def _sigma(values: list[float], ns: int, static: Any) -> bytes:
    d = row_dict(SIGMA_INPUTS, values, static, {})
    return log_proto.encode(
        "cosim.EstimateSigma", {"t": d["t"], **sigma_bounds(d["var"], d["q"], d["p_att"]), "bias": d["bias"]}
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
        "fixed_wing_setpoint": (FIXED_WING_SETPOINT, "cosim.FixedWingSetpoint"),
        "multirotor_setpoint": (MULTIROTOR_SETPOINT, "cosim.MultirotorSetpoint"),
        "commands": (COMMANDS, "cosim.Commands"),
    }
    out = {
        "truth": RowLayout(
            "truth", STATE, (state, _foxglove(LocationFix, _location), _foxglove(FrameTransforms, _transform))
        )
    }
    out.update({name: RowLayout(name, cols, (_cosim(title, cols),)) for name, (cols, title) in one.items()})
    # the bus's record is the state at the end of the control step (its t): logged at the tick
    out["energy"] = RowLayout("energy", (("log_t", 0), *ENERGY), (_cosim("cosim.Energy", ENERGY, lead=1),))
    sensors = Output("cosim.Sensors", lambda: log_proto.schema_data("cosim.Sensors"), _sensors)
    out["sensors"] = RowLayout("sensors", (("t", 0),), (sensors,))
    sigma = Output("cosim.EstimateSigma", lambda: log_proto.schema_data("cosim.EstimateSigma"), _sigma)
    out["sigma"] = RowLayout("sigma", SIGMA_INPUTS, (sigma,))
    return out


LAYOUTS: dict[str, RowLayout] = _layouts()
SETPOINT_LAYOUTS = {"cosim.FixedWingSetpoint": "fixed_wing_setpoint", "cosim.MultirotorSetpoint": "multirotor_setpoint"}


def row_width(layout: str, static: Any) -> int:
    """Columns of a row of ``layout`` with constant part ``static`` (maps: their keys; sensors:
    their record counts)."""
    st = dict(static)
    if layout == "sensors":
        return 1 + sum(n * _RECORD_WIDTH[name] for name, n in st["counts"])
    return sum(len(st[name]) if width == MAP else max(width, 1) for name, width in LAYOUTS[layout].columns)
