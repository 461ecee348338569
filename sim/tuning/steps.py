"""Closed-loop step tests in JSBSim (the nonlinear model, inner loops as implemented in the XML).

- :func:`haps_pitch_step`: HAPS trimmed (JSBSim trim), pitch hold engaged with the gains of
  ``gains.toml`` (or overrides), throttle held at trim, wings-level command; pitch command stepped
  by ``step_deg`` at t = 0. Returns time [s] and pitch change [rad].
- :func:`quad_roll_step`: quadrotor hovering on its FCS (gains of ``gains.toml`` or overrides),
  collective at the hover thrust; roll command stepped by ``step_deg``. Returns time [s], roll [rad].
- :func:`overshoot_pct`: (peak - step) / step [%] of a response to a step of size ``step``.
"""

from __future__ import annotations

import math

import numpy as np

from aircraft.haps.gains import HapsGains
from aircraft.quadrotor.gains import MultirotorGains


def overshoot_pct(y: np.ndarray, step: float) -> float:
    return max(0.0, 100.0 * (float(np.max(y / step)) - 1.0))


def haps_pitch_step(
    alt_m: float = 20_000.0,
    tas_mps: float = 29.7,
    step_deg: float = 2.0,
    seconds: float = 10.0,
    overrides: dict[str, float] | None = None,
):
    from sim.tuning.trim_haps import jsbsim_trim

    pt, plant = jsbsim_trim(alt_m, tas_mps)
    if plant is None:
        raise RuntimeError(f"HAPS does not trim at {alt_m} m, {tas_mps} m/s: {pt.reason}")
    plant.set_many(HapsGains.load().fcs_properties())
    plant.set_many(overrides or {})
    theta0 = plant["attitude/theta-rad"]
    plant.set_many({"ap/engage": 1.0, "ap/roll-cmd-rad": 0.0, "ap/pitch-cmd-rad": theta0 + math.radians(step_deg)})
    n = round(seconds / plant.dt)
    y = np.empty(n)
    for k in range(n):
        plant.step()
        y[k] = plant["attitude/theta-rad"] - theta0
    return plant.dt * np.arange(1, n + 1), y


def quad_roll_step(
    alt_m: float = 100.0, step_deg: float = 5.0, seconds: float = 1.5, overrides: dict[str, float] | None = None
):
    from sim.tuning.trim_quad import quad_plant, quad_trim

    trim = quad_trim(alt_m, 0.0)
    w = 0.76
    f_hover = ((-w + math.sqrt(w * w + 4 * (1 - w) * trim.throttle)) / (2 * (1 - w))) ** 2
    plant = quad_plant(alt_m)
    plant.set_many(MultirotorGains.load().fcs_properties())
    plant.set_many(overrides or {})
    plant.set_many(
        {
            "ap/armed": 1.0,
            "ap/landed": 0.0,
            "ap/thrust-cmd-norm": f_hover,
            "ap/roll-cmd-rad": 0.0,
            "ap/pitch-cmd-rad": 0.0,
            "ap/yaw-cmd-rad": plant["attitude/psi-rad"],
        }
    )
    plant["forces/hold-down"] = 1.0
    plant.step(int(0.5 / plant.dt))
    plant["forces/hold-down"] = 0.0
    phi0 = plant["attitude/phi-rad"]
    plant["ap/roll-cmd-rad"] = phi0 + math.radians(step_deg)
    n = round(seconds / plant.dt)
    y = np.empty(n)
    for k in range(n):
        plant.step()
        y[k] = plant["attitude/phi-rad"] - phi0
    return plant.dt * np.arange(1, n + 1), y
