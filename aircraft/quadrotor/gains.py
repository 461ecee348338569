"""Gains and limits of the quadrotor flight controller, loaded from ``gains.toml``.

The file is the single source of the values: every key must be present and unknown keys are
rejected (a typo must not silently fall back to a default). Angles are degrees in the file
(keys ending in ``_deg`` or ``_deg_s``) and radians in the dataclasses (``_rad``, ``_rad_s``).
Thrust values are fractions of the static sea-level maximum thrust (collective or per motor).

The outer-loop groups are used by :class:`aircraft.quadrotor.controller.MultirotorController`;
the inner-loop groups become JSBSim FCS properties through :meth:`MultirotorGains.fcs_properties`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, is_dataclass
from pathlib import Path
from typing import Any, get_type_hints

from aircraft.gains_file import GainsError, read_gains_toml

DEFAULT_PATH = Path(__file__).with_name("gains.toml")


@dataclass(frozen=True, slots=True)
class PositionGains:
    """Position P: position error [m] -> velocity demand [m/s]."""

    kp_xy: float
    kp_z: float


@dataclass(frozen=True, slots=True)
class VelocityGains:
    """Velocity PID: velocity error [m/s] -> acceleration demand [m/s^2] (D on measurement)."""

    kp_xy: float
    ki_xy: float
    kd_xy: float
    kp_z: float
    ki_z: float
    kd_z: float
    d_cutoff_hz: float


@dataclass(frozen=True, slots=True)
class LimitGains:
    """Speed [m/s], acceleration [m/s^2], tilt [rad], thrust [fraction] and yaw-rate limits."""

    max_speed_xy: float
    max_climb: float
    max_descent: float
    max_accel_xy: float
    max_tilt_rad: float
    hover_thrust: float
    thrust_min: float
    thrust_max: float
    thrust_xy_margin: float
    max_yaw_rate_rad_s: float


@dataclass(frozen=True, slots=True)
class TakeoffGains:
    """Take-off trigger [m] and climb-rate ramp [s]."""

    climb_margin: float
    ramp_s: float


@dataclass(frozen=True, slots=True)
class LandGains:
    """Land detector thresholds [m/s, fraction of hover thrust, s] and disarm delay [s]."""

    max_vz: float
    max_vxy: float
    thrust_ratio: float
    time_s: float
    disarm_delay_s: float


@dataclass(frozen=True, slots=True)
class AttitudeGains:
    """Attitude P [1/s] and Euler-rate limits [rad/s] (JSBSim FCS)."""

    kp_roll: float
    kp_pitch: float
    kp_yaw: float
    max_roll_rate_rad_s: float
    max_pitch_rate_rad_s: float
    max_yaw_rate_rad_s: float


@dataclass(frozen=True, slots=True)
class RateAxisGains:
    """Body-rate PID of one axis: rate error [rad/s] -> torque [per-motor thrust fraction]."""

    kp: float
    ki: float
    kd: float
    int_lim: float


@dataclass(frozen=True, slots=True)
class RateGains:
    """Body-rate PIDs (JSBSim FCS) and their D-term low-pass cut-off [Hz]."""

    d_cutoff_hz: float
    roll: RateAxisGains
    pitch: RateAxisGains
    yaw: RateAxisGains


@dataclass(frozen=True, slots=True)
class MixerGains:
    """Mixer yaw clip, motor idle and low-thrust boost [per-motor thrust fraction]."""

    yaw_max: float
    idle_thrust: float
    boost_max: float


@dataclass(frozen=True, slots=True)
class MultirotorGains:
    """All gains and limits of the multirotor controller (see ``gains.toml`` for each value)."""

    position: PositionGains
    velocity: VelocityGains
    limits: LimitGains
    takeoff: TakeoffGains
    land: LandGains
    attitude: AttitudeGains
    rate: RateGains
    mixer: MixerGains

    @classmethod
    def load(cls, path: str | Path | None = None) -> MultirotorGains:
        """Read a gains file (default: ``gains.toml`` beside this module)."""
        table, where = read_gains_toml(path, DEFAULT_PATH)
        return _build(cls, table, where)

    def fcs_properties(self) -> dict[str, float]:
        """Inner-loop gains as the JSBSim properties of ``systems/flight-control.xml``."""
        a, r, m = self.attitude, self.rate, self.mixer
        props = {
            "ap/kp-roll": a.kp_roll,
            "ap/kp-pitch": a.kp_pitch,
            "ap/kp-yaw": a.kp_yaw,
            "ap/roll-rate-max-rps": a.max_roll_rate_rad_s,
            "ap/pitch-rate-max-rps": a.max_pitch_rate_rad_s,
            "ap/yaw-rate-max-rps": a.max_yaw_rate_rad_s,
            "ap/rate-d-cutoff-rps": 2.0 * math.pi * r.d_cutoff_hz,
            "ap/yaw-mix-max": m.yaw_max,
            "ap/motor-idle-thrust": m.idle_thrust,
            "ap/mix-boost-max": m.boost_max,
        }
        for axis in ("roll", "pitch", "yaw"):
            g: RateAxisGains = getattr(r, axis)
            props[f"ap/kp-{axis}-rate"] = g.kp
            props[f"ap/ki-{axis}-rate"] = g.ki
            props[f"ap/kd-{axis}-rate"] = g.kd
            props[f"ap/int-lim-{axis}-rate"] = g.int_lim
        return props


def _field_name(key: str) -> tuple[str, float]:
    """Dataclass field for a file key, and the factor from file to code units (deg -> rad)."""
    if key.endswith("_deg_s"):
        return key[: -len("_deg_s")] + "_rad_s", math.pi / 180.0
    if key.endswith("_deg"):
        return key[: -len("_deg")] + "_rad", math.pi / 180.0
    return key, 1.0


def _file_key(name: str) -> str:
    """File key of a dataclass field (inverse of :func:`_field_name`)."""
    if name.endswith("_rad_s"):
        return name[: -len("_rad_s")] + "_deg_s"
    if name.endswith("_rad"):
        return name[: -len("_rad")] + "_deg"
    return name


def _build(cls: type, table: dict[str, Any], where: str) -> Any:
    """Instantiate dataclass ``cls`` from a TOML table, strictly (no missing or unknown keys)."""
    hints = get_type_hints(cls)
    expected = {_file_key(f.name) for f in fields(cls)}
    unknown = sorted(set(table) - expected)
    if unknown:
        raise GainsError(f"{where}: unknown key(s) {', '.join(unknown)}; allowed here: {', '.join(sorted(expected))}")
    missing = sorted(expected - set(table))
    if missing:
        raise GainsError(f"{where}: missing key(s) {', '.join(missing)}")
    values: dict[str, Any] = {}
    for key, raw in table.items():
        name, factor = _field_name(key)
        kind = hints[name]
        if isinstance(kind, type) and is_dataclass(kind):
            if not isinstance(raw, dict):
                raise GainsError(f"{where}: [{key}] must be a table")
            values[name] = _build(kind, raw, f"{where} [{key}]")
        elif isinstance(raw, bool) or not isinstance(raw, (int, float)):
            raise GainsError(f"{where}: {key} must be a number, got {raw!r}")
        else:
            values[name] = float(raw) * factor
    return cls(**values)
