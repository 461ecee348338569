"""Common base of every sensor and estimator configuration: strict, frozen, finite.

Configs are pydantic models so that a scenario can build them from TOML tables and an invalid
value fails with a message naming the field, e.g. ``ImuConfig: rate_hz: Input should be greater
than 0``. Units are SI and stated per field.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, ValidationError


class SensorConfigError(ValueError):
    """A sensor or estimator configuration (or a fault) is invalid; the message names the field."""


class StrictConfig(BaseModel):
    """Rejects unknown fields, NaN and infinities; instances are immutable."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    @classmethod
    def build(cls, **fields):
        """Validated instance; raises :class:`SensorConfigError` with one line per bad field."""
        try:
            return cls(**fields)
        except ValidationError as exc:
            lines = [f"{'.'.join(str(p) for p in e['loc']) or '<root>'}: {e['msg']}" for e in exc.errors()]
            raise SensorConfigError(f"{cls.__name__}: " + "; ".join(lines)) from exc
