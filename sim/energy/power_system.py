"""One vehicle's electrical bus: solar array in; propulsion, avionics and payload out; the
battery takes or gives the difference.

Per step of ``dt`` [s] (the vehicle's control rate), from the true state (position, attitude) and
JSBSim's shaft power of every motor: array power (:mod:`sim.energy.solar`), propulsion electrical
power = shaft power / motor efficiency, loads = avionics + payload, bus power = solar -
propulsion - loads into :class:`sim.energy.battery.Battery`. Cumulative energies [Wh] are kept so
that the balance  solar - propulsion - loads = delta stored + losses + curtailed - shortfall
can be checked from the log.

Depletion: the first step whose demand the empty battery cannot meet sets ``depleted``; the owner
then stops the motors (the aircraft glides) for the rest of the run.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime

from sim.core.state import VehicleState
from sim.energy.battery import Battery
from sim.energy.params import EnergyParams
from sim.energy.solar import SunTracker, array_power

_HP_TO_W = 745.69987


@dataclass
class EnergyRecord:
    """The bus at one instant [W, Wh, 0..1] and cumulative energies since the start [Wh]."""

    t: float = 0.0
    state_of_charge: float = 0.0
    energy_wh: float = 0.0
    solar_w: float = 0.0
    propulsion_w: float = 0.0
    loads_w: float = 0.0
    total_w: float = 0.0  # solar - propulsion - loads: > 0 charging
    battery_w: float = 0.0  # into the cells, after conversion losses
    loss_w: float = 0.0
    curtailed_w: float = 0.0
    shortfall_w: float = 0.0
    sun_elevation_deg: float = 0.0
    incidence_cos: float = 0.0
    depleted: bool = False
    cumulative_wh: dict[str, float] = field(
        default_factory=lambda: dict.fromkeys(("solar", "propulsion", "loads", "loss", "curtailed", "shortfall"), 0.0)
    )

    def as_dict(self) -> dict:
        d = {k: getattr(self, k) for k in self.__dataclass_fields__ if k != "cumulative_wh"}
        d["cumulative_wh"] = dict(self.cumulative_wh)
        return d


class PowerSystem:
    """The bus of one vehicle (see the module docstring)."""

    def __init__(self, params: EnergyParams, epoch: datetime, initial_soc: float | None = None):
        self.params = params
        self.sun = SunTracker(epoch, params.atmosphere)
        self.battery = Battery(params.battery, initial_soc)
        self.record = EnergyRecord(state_of_charge=self.battery.soc, energy_wh=self.battery.energy_wh)

    @property
    def depleted(self) -> bool:
        return self.record.depleted

    def step(self, truth: VehicleState, shaft_power_hp: list[float], dt: float) -> EnergyRecord:
        """Advance ``dt`` [s] with the powers at ``truth`` (held over the step)."""
        p = self.params
        sun = self.sun.sample(truth.t, truth.lat_deg, truth.lon_deg, truth.alt_msl_m)
        solar, cos_inc = array_power(p.array, sun, truth.euler)
        propulsion = sum(shaft_power_hp) * _HP_TO_W / p.loads.motor_efficiency
        loads = p.loads.avionics_w + p.loads.payload_w
        total = solar - propulsion - loads
        b = self.battery.step(total, dt)
        r = self.record
        r.t = truth.t + dt
        r.state_of_charge, r.energy_wh = self.battery.soc, self.battery.energy_wh
        r.solar_w, r.propulsion_w, r.loads_w, r.total_w = solar, propulsion, loads, total
        r.battery_w, r.loss_w, r.curtailed_w, r.shortfall_w = b.stored_w, b.loss_w, b.curtailed_w, b.shortfall_w
        r.sun_elevation_deg, r.incidence_cos = sun.elevation_deg, cos_inc
        c, h = r.cumulative_wh, dt / 3600.0
        for key, w in (
            ("solar", solar),
            ("propulsion", propulsion),
            ("loads", loads),
            ("loss", b.loss_w),
            ("curtailed", b.curtailed_w),
            ("shortfall", b.shortfall_w),
        ):
            c[key] += w * h
        if b.shortfall_w > 1e-9 and self.battery.energy_wh <= 0.0:
            r.depleted = True
        return r
