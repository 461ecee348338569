"""The airframes a scenario can name, with their JSBSim model, rates and flight controller.

A flight controller turns a guidance setpoint and the vehicle's estimate into JSBSim property
commands (see :class:`FlightController`); its gains live in the airframe folder's gains file.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, Protocol

import jsbsim

from aircraft import airframe_dir
from sim.core.state import VehicleState


class FlightController(Protocol):
    """Setpoint + estimate -> JSBSim property commands, called at the airframe's control rate."""

    debug: dict[str, float]
    gains: object  # the airframe's gains (aircraft/<airframe>/gains.py)

    def reset(self, state: VehicleState) -> None: ...

    def update(self, state: VehicleState, setpoint, dt: float) -> dict[str, float]: ...


@dataclass(frozen=True, slots=True)
class Airframe:
    """One flyable airframe: JSBSim model, its integration rate, the controller and its rate."""

    name: str
    kind: Literal["fixed_wing", "multirotor"]
    jsbsim_model: str
    folder: Path | None  # None: a model shipped with JSBSim
    plant_hz: int
    control_hz: int
    radius_m: float  # radius of a sphere around the airframe [m] (separation, surveillance, collisions)
    # highest sink rate [m/s] at which the landing gear may first touch the ground (faster: a crash)
    crash_sink_mps: float
    ceiling_m: float  # highest altitude MSL [m] (ISA) a scenario may fly it to
    controller: str  # "module:Class" with a ctor taking the gains object
    gains: str  # "module:Class" with ``load(path=None)``
    description: str
    # "module:function(plant)" trimming where JSBSim's own trim cannot (None: JSBSim's trim only)
    level_trim: str | None = None
    # (min, max) equivalent airspeed [m/s] it flies; a fixed wing's cruise speed must map into it
    eas_envelope_mps: tuple[float, float] | None = None
    # electrical power system (solar array, battery, loads): ``energy.toml`` in the airframe folder
    energy: bool = False

    @property
    def jsbsim_file(self) -> Path:
        """The JSBSim model file (``<folder>/<model>.xml``, or JSBSim's shipped one)."""
        folder = (
            self.folder
            if self.folder is not None
            else Path(jsbsim.get_default_root_dir()) / "aircraft" / self.jsbsim_model
        )
        return folder / f"{self.jsbsim_model}.xml"

    @property
    def energy_file(self) -> Path | None:
        return self.folder / "energy.toml" if self.energy and self.folder is not None else None

    def make_controller(self, gains_path: Path | None = None) -> FlightController:
        gains = resolve(self.gains).load(gains_path)
        return resolve(self.controller)(gains)


def resolve(ref: str):
    """The object named by ``"module:attr"``."""
    module, _, attr = ref.partition(":")
    return getattr(importlib.import_module(module), attr)


AIRFRAMES: dict[str, Airframe] = {
    a.name: a
    for a in (
        Airframe(
            name="haps",
            kind="fixed_wing",
            jsbsim_model="haps",
            folder=airframe_dir("haps"),
            plant_hz=120,
            control_hz=10,
            radius_m=12.5,
            crash_sink_mps=1.0,
            ceiling_m=23_000.0,  # top of the trim table (README "Trim"); Zephyr's record 23.2 km
            eas_envelope_mps=(7.3, 12.0),  # the autopilot's demand limits: 1.08 x the 1-g stall EAS 6.74 m/s
            controller="aircraft.haps.autopilot:HapsAutopilot",
            gains="aircraft.haps.autopilot:HapsGains",
            description="Zephyr-class solar-electric HAPS, 25 m span, 75 kg (aircraft/haps/README.md)",
            level_trim="sim.tuning.trim_haps:level_trim",
            energy=True,
        ),
        Airframe(
            name="quadrotor",
            kind="multirotor",
            jsbsim_model="quadrotor",
            folder=airframe_dir("quadrotor"),
            plant_hz=240,
            control_hz=60,
            radius_m=0.45,
            crash_sink_mps=3.0,
            ceiling_m=7_800.0,  # ISA altitude where static thrust falls to 2 x weight (4.6 at sea level)
            controller="aircraft.quadrotor.controller:MultirotorController",
            gains="aircraft.quadrotor.controller:MultirotorGains",
            description="F450-derived 1.4 kg quadrotor (aircraft/quadrotor/README.md)",
        ),
    )
}


def get_airframe(name: str) -> Airframe:
    """The airframe called ``name``; KeyError naming the known ones otherwise."""
    try:
        return AIRFRAMES[name]
    except KeyError:
        raise KeyError(f"unknown aircraft {name!r} (known: {', '.join(sorted(AIRFRAMES))})") from None
