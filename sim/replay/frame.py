"""A topic's decoded messages as one flat table (pandas), for analysis and export.

Each message (a dict, or a protobuf message turned into one) becomes a row:
- nested objects become dotted columns (``cumulative_wh.solar``);
- lists of numbers, booleans or strings become one column per index (``pos_ned.0``,
  ``pos_ned.1``, ``pos_ned.2``); a shorter list leaves the missing columns empty;
- lists holding objects or lists (plan vertices, threat lists) become one JSON text column,
  so every cell is a scalar and the table writes to CSV and Parquet alike.
The index is the message's log time in seconds of sim time (``sim_time_s``).
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

from google.protobuf.descriptor import FieldDescriptor
from google.protobuf.message import Message

if TYPE_CHECKING:
    import pandas as pd

INDEX = "sim_time_s"

Scalar = float | int | bool | str | None


_TIME_TYPES = ("google.protobuf.Timestamp", "google.protobuf.Duration")


def as_dict(message: Any) -> dict:
    """A decoded message as a dict: JSON messages already are; protobuf messages by field name,
    every field (defaults included), enums by name, timestamps and durations in seconds."""
    if isinstance(message, dict):
        return message
    if isinstance(message, Message):
        return _proto_dict(message)
    raise TypeError(f"not a decoded message: {type(message).__name__}")


def _proto_dict(message: Message) -> dict:
    return {f.name: _proto_value(f, getattr(message, f.name)) for f in message.DESCRIPTOR.fields}


def _proto_value(f: FieldDescriptor, value: Any) -> Any:
    if f.is_repeated:
        return [_proto_item(f, v) for v in value]
    return _proto_item(f, value)


def _proto_item(f: FieldDescriptor, value: Any) -> Any:
    if f.message_type is not None:
        if f.message_type.full_name in _TIME_TYPES:
            return value.seconds + value.nanos * 1e-9
        return _proto_dict(value)
    if f.enum_type is not None:
        return f.enum_type.values_by_number[value].name
    if isinstance(value, bytes):
        return value.hex()
    return value


def flatten_message(message: dict, prefix: str = "") -> dict[str, Scalar]:
    """One message as dotted column names -> scalar cells (see the module docstring)."""
    row: dict[str, Scalar] = {}
    for key, value in message.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            row.update(flatten_message(value, name + "."))
        elif isinstance(value, list):
            if all(not isinstance(v, dict | list) for v in value):
                row.update({f"{name}.{i}": v for i, v in enumerate(value)})
            else:
                row[name] = json.dumps(value, separators=(",", ":"))
        else:
            row[name] = value
    return row


def frame(times: Iterable[float], messages: Iterable[Any]) -> pd.DataFrame:
    """A DataFrame with one row per message, flattened columns, indexed by sim time [s]."""
    import pandas as pd

    rows = [flatten_message(as_dict(m)) for m in messages]
    return pd.DataFrame.from_records(rows, index=pd.Index(list(times), dtype=float, name=INDEX))
