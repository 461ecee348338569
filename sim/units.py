"""Quantities in scenario files: a bare number in the field's unit, or a string with a unit.

Each dimension has an SI unit (and a unit assumed for a bare number, e.g. degrees for angles,
since files are written by people). ``"18 km"``, ``"50 kt"``, ``"90 deg"`` and ``"2.5 h"`` are
accepted; a unit of the wrong dimension (``"25 km"`` for a speed) is an error naming both.
"""

from __future__ import annotations

import math
import re
from typing import Annotated

from pydantic import BeforeValidator

# dimension -> unit -> factor to SI (radians for angles)
_UNITS: dict[str, dict[str, float]] = {
    "length": {"m": 1.0, "km": 1000.0, "ft": 0.3048, "nmi": 1852.0, "NM": 1852.0},
    "speed": {
        "m/s": 1.0,
        "km/h": 1 / 3.6,
        "kt": 1852.0 / 3600.0,
        "kts": 1852.0 / 3600.0,
        "ft/s": 0.3048,
        "ft/min": 0.3048 / 60.0,
    },
    "angle": {"deg": math.pi / 180.0, "rad": 1.0},
    "time": {"s": 1.0, "min": 60.0, "h": 3600.0, "ms": 1e-3},
    "frequency": {"Hz": 1.0},
}
# the unit a bare number is read in
_BARE_UNIT = {"length": "m", "speed": "m/s", "angle": "deg", "time": "s", "frequency": "Hz"}

_QUANTITY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(\S+)?\s*$")


def _unit_dimension(unit: str) -> str | None:
    return next((dim for dim, table in _UNITS.items() if unit in table), None)


def to_si(value, dimension: str) -> float:
    """Parse ``value`` (number or ``"<number> <unit>"``) to SI in ``dimension``.

    Raises ValueError with a message that names the expected units.
    """
    table = _UNITS[dimension]
    if isinstance(value, bool):
        raise ValueError(f"expected a {dimension}, got a boolean")
    if isinstance(value, (int, float)):
        v = float(value) * table[_BARE_UNIT[dimension]]
    elif isinstance(value, str):
        m = _QUANTITY.match(value)
        if not m:
            raise ValueError(f"expected a {dimension} such as '10 {_BARE_UNIT[dimension]}', got {value!r}")
        number, unit = float(m.group(1)), m.group(2) or _BARE_UNIT[dimension]
        if unit not in table:
            other = _unit_dimension(unit)
            known = ", ".join(table)
            if other:
                raise ValueError(f"wrong unit: '{unit}' is a {other}, this field is a {dimension} ({known})")
            raise ValueError(f"unknown unit '{unit}' for a {dimension} ({known})")
        v = number * table[unit]
    else:
        raise ValueError(f"expected a {dimension}, got {type(value).__name__}")
    if not math.isfinite(v):
        raise ValueError(f"expected a finite {dimension}, got {value!r}")
    return v


def quantity(
    dimension: str, lo: float | None = None, hi: float | None = None, *, lo_open: bool = False
) -> BeforeValidator:
    """The validator of a quantity field, ``Annotated[float, quantity(...)]``: parsed to SI,
    range-checked in the bare unit (``lo``/``hi`` are given in that unit, e.g. degrees for
    angles) so that messages read as the file does."""
    bare = _BARE_UNIT[dimension]
    scale = _UNITS[dimension][bare]

    def parse(value: object) -> float:
        si = to_si(value, dimension)
        shown = si / scale
        below = lo is not None and (shown <= lo if lo_open else shown < lo)
        if below or (hi is not None and shown > hi):
            lo_s = "-inf" if lo is None else f"{lo:g}"
            hi_s = "inf" if hi is None else f"{hi:g}"
            bracket = "(" if lo_open else "["
            raise ValueError(f"out of range: {shown:g} {bare} not in {bracket}{lo_s}, {hi_s}] {bare}")
        return si

    return BeforeValidator(parse)


Length = Annotated[float, quantity("length")]
"""[m]; bare numbers are metres."""
Speed = Annotated[float, quantity("speed")]
"""[m/s]; bare numbers are m/s."""
Angle = Annotated[float, quantity("angle")]
"""[rad]; bare numbers are DEGREES (files are for people)."""
Duration = Annotated[float, quantity("time")]
"""[s]; bare numbers are seconds."""
