"""A battery as stored energy with charge/discharge efficiencies and power limits.

Sign convention: bus power ``p_bus`` [W] > 0 offered to the battery (charging), < 0 demanded from
it (discharging). Stored energy in Wh; state of charge = stored / usable capacity, 0..1.
"""

from __future__ import annotations

from dataclasses import dataclass

from sim.energy.params import BatteryParams


@dataclass(frozen=True, slots=True)
class BatteryStep:
    """Powers over one step [W]: into the cells (signed, after efficiency), lost in conversion,
    offered but not taken (battery full or charge limit: the MPPT backs off), demanded but not
    delivered (battery empty or discharge limit)."""

    stored_w: float
    loss_w: float
    curtailed_w: float
    shortfall_w: float


class Battery:
    def __init__(self, params: BatteryParams, soc: float | None = None):
        soc = params.initial_soc if soc is None else soc
        if not 0.0 <= soc <= 1.0:
            raise ValueError(f"battery: state of charge {soc} outside [0, 1]")
        self.params = params
        self.capacity_wh = params.capacity_wh
        self.energy_wh = soc * self.capacity_wh

    @property
    def soc(self) -> float:
        return self.energy_wh / self.capacity_wh

    def step(self, p_bus: float, dt: float) -> BatteryStep:
        """Exchange ``p_bus`` [W] with the bus for ``dt`` [s]."""
        p = self.params
        if p_bus >= 0.0:
            room_w = (self.capacity_wh - self.energy_wh) * 3600.0 / (dt * p.charge_efficiency)
            taken = min(p_bus, p.max_charge_w, room_w)
            stored = taken * p.charge_efficiency
            self.energy_wh = min(self.capacity_wh, self.energy_wh + stored * dt / 3600.0)
            return BatteryStep(stored, taken - stored, p_bus - taken, 0.0)
        demand = min(-p_bus, p.max_discharge_w)
        drawn = min(demand / p.discharge_efficiency, self.energy_wh * 3600.0 / dt)
        delivered = drawn * p.discharge_efficiency
        self.energy_wh = max(0.0, self.energy_wh - drawn * dt / 3600.0)
        return BatteryStep(-drawn, drawn - delivered, 0.0, -p_bus - delivered)
