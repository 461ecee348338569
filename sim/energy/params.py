"""Parameters of a solar aircraft's power system, read strictly from the airframe's
``energy.toml`` (every key required, no unknown keys). Units SI: W, Wh, m^2, m; fractions 0..1."""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np


class EnergyConfigError(ValueError):
    """An energy file is unreadable or invalid; the message names the file and the key."""


@dataclass(frozen=True, slots=True)
class ArrayParams:
    area_m2: float
    cell_efficiency: float
    mppt_efficiency: float
    normal_body: tuple[float, float, float]  # unit normal of the cells, body FRD axes


@dataclass(frozen=True, slots=True)
class BatteryParams:
    mass_kg: float
    cell_specific_energy_wh_kg: float
    packaging_factor: float
    charge_efficiency: float
    discharge_efficiency: float
    max_charge_w: float
    max_discharge_w: float
    initial_soc: float

    @property
    def capacity_wh(self) -> float:
        """Usable pack energy [Wh]."""
        return self.mass_kg * self.cell_specific_energy_wh_kg * self.packaging_factor


@dataclass(frozen=True, slots=True)
class LoadParams:
    avionics_w: float
    payload_w: float
    motor_efficiency: float


@dataclass(frozen=True, slots=True)
class AtmosphereParams:
    precipitable_water_cm: float
    water_scale_height_m: float
    aod500: float
    aerosol_scale_height_m: float
    ozone_atm_cm: float


@dataclass(frozen=True, slots=True)
class EnergyParams:
    array: ArrayParams
    battery: BatteryParams
    loads: LoadParams
    atmosphere: AtmosphereParams

    @classmethod
    def load(cls, path: str | Path) -> EnergyParams:
        p = Path(path)
        try:
            with p.open("rb") as fh:
                data = tomllib.load(fh)
        except OSError as exc:
            raise EnergyConfigError(f"{p}: cannot read energy file ({exc.strerror})") from None
        except tomllib.TOMLDecodeError as exc:
            raise EnergyConfigError(f"{p}: not valid TOML: {exc}") from None
        parts = {"array": ArrayParams, "battery": BatteryParams, "loads": LoadParams, "atmosphere": AtmosphereParams}
        if set(data) != set(parts):
            raise EnergyConfigError(f"{p}: tables must be exactly {sorted(parts)}, got {sorted(data)}")
        built = {name: _section(p, name, kind, data[name]) for name, kind in parts.items()}
        out = cls(**built)
        out._check(p)
        return out

    def _check(self, p: Path) -> None:
        fractions = {
            "array.cell_efficiency": self.array.cell_efficiency,
            "array.mppt_efficiency": self.array.mppt_efficiency,
            "battery.packaging_factor": self.battery.packaging_factor,
            "battery.charge_efficiency": self.battery.charge_efficiency,
            "battery.discharge_efficiency": self.battery.discharge_efficiency,
            "battery.initial_soc": self.battery.initial_soc,
            "loads.motor_efficiency": self.loads.motor_efficiency,
        }
        for key, v in fractions.items():
            if not 0.0 <= v <= 1.0 or (v == 0.0 and key != "battery.initial_soc"):
                raise EnergyConfigError(f"{p}: {key} = {v} must be in (0, 1]")
        if abs(float(np.linalg.norm(self.array.normal_body)) - 1.0) > 1e-6:
            raise EnergyConfigError(f"{p}: array.normal_body must be a unit vector")
        if self.battery.capacity_wh <= 0.0:
            raise EnergyConfigError(f"{p}: battery capacity must be > 0 Wh")


def _section(p: Path, name: str, kind, table: dict):
    want = {f.name for f in fields(kind)}
    if set(table) != want:
        missing, extra = sorted(want - set(table)), sorted(set(table) - want)
        raise EnergyConfigError(f"{p}: [{name}] missing {missing}, unknown {extra}")
    values: dict[str, float | tuple[float, ...]] = {}
    for k, v in table.items():
        if k == "normal_body":
            if not (isinstance(v, list) and len(v) == 3):
                raise EnergyConfigError(f"{p}: {name}.{k} must be a list of 3 numbers")
            values[k] = tuple(float(x) for x in v)
        elif isinstance(v, bool) or not isinstance(v, int | float) or v < 0:
            raise EnergyConfigError(f"{p}: {name}.{k} must be a number >= 0, got {v!r}")
        else:
            values[k] = float(v)
    return kind(**values)
