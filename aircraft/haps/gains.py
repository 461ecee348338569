"""Gains and limits of the HAPS autopilot, loaded from ``gains.toml``.

The file is the single source of the values: every key must be present, and unknown sections or
keys are rejected with the list of allowed ones (a typo must not fall back to a default).
The file groups keys in sections; the dataclass is flat (``gains.roll_limit_rad``). Angles are
degrees in the file (keys ending ``_deg`` or ``_deg_s``) and radians in code (``_rad``,
``_rad_s``); everything else is SI as named in the file's comments.

Users: :class:`aircraft.haps.autopilot.HapsAutopilot` (TECS outer loops, and the ``[inner]``
section as JSBSim ``ap/*`` properties) and :meth:`guidance.l1.L1Guidance.for_airframe`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from aircraft.gains_file import GainsError, read_gains_toml

DEFAULT_PATH = Path(__file__).with_name("gains.toml")

# Equivalent airspeed -> dynamic pressure: 0.5 * rho0 * EAS^2 [Pa], and Pa -> lbf/ft^2 (JSBSim).
RHO0 = 1.225  # ISA sea-level density [kg/m^3]
PA_TO_PSF = 0.020885434273039


def _in(section: str) -> Any:
    return field(metadata={"section": section})


@dataclass(frozen=True, slots=True)
class HapsGains:
    """All HAPS autopilot gains and limits (units and meaning: comments in ``gains.toml``)."""

    # [limits]
    roll_limit_rad: float = _in("limits")
    roll_rate_limit_rad_s: float = _in("limits")
    turn_radius_min_m: float = _in("limits")
    pitch_min_rad: float = _in("limits")
    pitch_max_rad: float = _in("limits")
    throttle_min: float = _in("limits")
    throttle_max: float = _in("limits")
    climb_rate_max: float = _in("limits")
    sink_rate_max: float = _in("limits")
    accel_max: float = _in("limits")
    eas_min: float = _in("limits")
    eas_max: float = _in("limits")
    eas_underspeed: float = _in("limits")
    # [schedule]
    climb_eas: float = _in("schedule")
    descent_eas: float = _in("schedule")
    schedule_band_m: float = _in("schedule")
    # [tecs]
    alt_time_const_s: float = _in("tecs")
    spd_time_const_s: float = _in("tecs")
    spd_weight: float = _in("tecs")
    thr_damp: float = _in("tecs")
    thr_integ: float = _in("tecs")
    thr_integ_limit: float = _in("tecs")
    pitch_damp: float = _in("tecs")
    pitch_integ: float = _in("tecs")
    vdot_filter_s: float = _in("tecs")
    tas_filter_s: float = _in("tecs")
    # [feedforward]
    mass_kg: float = _in("feedforward")
    wing_area_m2: float = _in("feedforward")
    cd0: float = _in("feedforward")
    k_induced: float = _in("feedforward")
    prop_efficiency: float = _in("feedforward")
    power_max_w: float = _in("feedforward")
    # [inner]
    kp_roll: float = _in("inner")
    ki_roll: float = _in("inner")
    kd_roll: float = _in("inner")
    k_roll_yaw: float = _in("inner")
    kp_pitch: float = _in("inner")
    ki_pitch: float = _in("inner")
    kd_pitch: float = _in("inner")
    kr_yaw: float = _in("inner")
    kbeta_yaw: float = _in("inner")
    k_ari: float = _in("inner")
    sched_eas_ref: float = _in("inner")
    sched_min: float = _in("inner")
    sched_max: float = _in("inner")
    # [l1]
    l1_period_s: float = _in("l1")
    l1_damping: float = _in("l1")
    l1_turn_lead_s: float = _in("l1")
    l1_distance_min_m: float = _in("l1")

    @classmethod
    def load(cls, path: str | Path | None = None) -> HapsGains:
        """Read a gains file (default: ``gains.toml`` beside this module)."""
        table, where = read_gains_toml(path, DEFAULT_PATH)
        return cls(**_flatten(table, where))

    def fcs_properties(self) -> dict[str, float]:
        """The ``[inner]`` gains and the attitude limits as JSBSim properties of
        ``systems/attitude_hold.xml`` (gain schedule reference as dynamic pressure [psf])."""
        return {
            "ap/kp-roll": self.kp_roll,
            "ap/ki-roll": self.ki_roll,
            "ap/kd-roll": self.kd_roll,
            "ap/k-roll-yaw": self.k_roll_yaw,
            "ap/kp-pitch": self.kp_pitch,
            "ap/ki-pitch": self.ki_pitch,
            "ap/kd-pitch": self.kd_pitch,
            "ap/kr-yaw": self.kr_yaw,
            "ap/kbeta-yaw": self.kbeta_yaw,
            "ap/k-ari": self.k_ari,
            "ap/qbar-ref-psf": 0.5 * RHO0 * self.sched_eas_ref**2 * PA_TO_PSF,
            "ap/sched-min": self.sched_min,
            "ap/sched-max": self.sched_max,
            "ap/roll-limit-rad": self.roll_limit_rad,
            "ap/pitch-min-rad": self.pitch_min_rad,
            "ap/pitch-max-rad": self.pitch_max_rad,
        }


def _file_key(name: str) -> tuple[str, float]:
    """File key of a dataclass field, and the factor from file to code units (deg -> rad)."""
    if name.endswith("_rad_s"):
        return name[: -len("_rad_s")] + "_deg_s", math.pi / 180.0
    if name.endswith("_rad"):
        return name[: -len("_rad")] + "_deg", math.pi / 180.0
    return name, 1.0


def _flatten(table: dict[str, Any], where: str) -> dict[str, float]:
    """Field values from the sectioned TOML table, strictly (no missing or unknown keys)."""
    sections: dict[str, dict[str, tuple[str, float]]] = {}
    for f in fields(HapsGains):
        key, factor = _file_key(f.name)
        sections.setdefault(f.metadata["section"], {})[key] = (f.name, factor)
    unknown = sorted(set(table) - set(sections))
    if unknown:
        raise GainsError(f"{where}: unknown section(s) {', '.join(unknown)}; allowed: {', '.join(sorted(sections))}")
    values: dict[str, float] = {}
    for sec, keys in sections.items():
        given = table.get(sec)
        if not isinstance(given, dict):
            raise GainsError(f"{where}: missing section [{sec}]")
        unknown = sorted(set(given) - set(keys))
        if unknown:
            raise GainsError(
                f"{where} [{sec}]: unknown key(s) {', '.join(unknown)}; allowed here: {', '.join(sorted(keys))}"
            )
        missing = sorted(set(keys) - set(given))
        if missing:
            raise GainsError(f"{where} [{sec}]: missing key(s) {', '.join(missing)}")
        for key, raw in given.items():
            if isinstance(raw, bool) or not isinstance(raw, (int, float)):
                raise GainsError(f"{where} [{sec}]: {key} must be a number, got {raw!r}")
            name, factor = keys[key]
            values[name] = float(raw) * factor
    return values
