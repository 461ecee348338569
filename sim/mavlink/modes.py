"""Flight modes as the bridge names them, and their MAVLink encoding.

With MAV_AUTOPILOT_GENERIC a GCS has no firmware-specific mode table, so each mode is sent as a
``custom_mode`` number (its index here) with MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, plus the standard
base_mode flags that describe it (a GCS that only understands the standard flags still shows
"Auto"/"Guided"/"Manual"). Incoming requests are decoded the other way: by custom_mode when the
custom flag is set, else by the standard flags.
"""

from __future__ import annotations

from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mav


@dataclass(frozen=True, slots=True)
class Mode:
    name: str
    custom_mode: int
    flags: int  # MAV_MODE_FLAG bits other than CUSTOM_MODE_ENABLED and SAFETY_ARMED


_STAB = mav.MAV_MODE_FLAG_STABILIZE_ENABLED
MODES: dict[str, Mode] = {
    m.name: m
    for m in (
        Mode("MANUAL", 0, mav.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED | _STAB),
        Mode("HOLD", 1, mav.MAV_MODE_FLAG_GUIDED_ENABLED | _STAB),
        Mode("AUTO", 2, mav.MAV_MODE_FLAG_AUTO_ENABLED | mav.MAV_MODE_FLAG_GUIDED_ENABLED | _STAB),
        Mode("GUIDED", 3, mav.MAV_MODE_FLAG_GUIDED_ENABLED | _STAB),
    )
}
_BY_NUMBER = {m.custom_mode: m for m in MODES.values()}


def base_mode(mode: Mode, armed: bool) -> int:
    """HEARTBEAT ``base_mode`` for ``mode`` (custom flag always set)."""
    armed_flag = mav.MAV_MODE_FLAG_SAFETY_ARMED if armed else 0
    return mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mode.flags | armed_flag


def decode_mode(base: int, custom: int) -> Mode | None:
    """The mode a SET_MODE / MAV_CMD_DO_SET_MODE asks for, or ``None`` if it names none of ours."""
    if base & mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
        return _BY_NUMBER.get(custom)
    if base & mav.MAV_MODE_FLAG_AUTO_ENABLED:
        return MODES["AUTO"]
    if base & mav.MAV_MODE_FLAG_GUIDED_ENABLED:
        return MODES["GUIDED"]
    if base & mav.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED:
        return MODES["MANUAL"]
    return None
