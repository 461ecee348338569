"""Loop analysis shared by every controller loop: margins and closed-loop figures, delays.

Margins from ``control.stability_margins`` (gain margin [dB], phase margin [deg], their
frequencies [rad/s]); bandwidth of the closed loop (-3 dB) [rad/s]; step info of the closed loop
(overshoot [%], 10-90 % rise time [s], 2 % settling time [s]). The loops themselves are built in
:mod:`sim.tuning.loops_haps` and :mod:`sim.tuning.loops_quad`; :mod:`sim.tuning.catalog` lists
them per airframe.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import control as ct
import numpy as np

S = ct.tf("s")


@dataclass
class LoopReport:
    """Margins and closed-loop figures of one loop (frequencies rad/s, angles deg, dB)."""

    name: str
    crossover_rad_s: float
    phase_margin_deg: float
    gain_margin_db: float
    phase_crossover_rad_s: float
    bandwidth_rad_s: float
    overshoot_pct: float
    rise_time_s: float
    settling_time_s: float

    def row(self) -> dict:
        return dict(self.__dict__)


def analyse(name: str, L, T) -> LoopReport:
    """Margins of open loop ``L`` and step/bandwidth figures of closed loop ``T`` (step figures
    NaN when the step never rises through 90 % within python-control's horizon)."""
    gm, pm, _, wpc, wgc, _ = ct.stability_margins(L)
    try:
        info = ct.step_info(T, SettlingTimeThreshold=0.02)
    except IndexError:
        info = dict.fromkeys(("Overshoot", "RiseTime", "SettlingTime"), math.nan)
    bw = ct.bandwidth(T)
    return LoopReport(
        name,
        float(wgc),
        float(pm),
        20 * math.log10(gm) if np.isfinite(gm) and gm > 0 else math.inf,
        float(wpc),
        float(bw),
        float(info["Overshoot"]),
        float(info["RiseTime"]),
        float(info["SettlingTime"]),
    )


def pade_delay(seconds: float, order: int = 2):
    """Pade approximation of a pure delay of ``seconds`` (unity for no delay)."""
    if seconds <= 0:
        return ct.tf([1.0], [1.0])
    num, den = ct.pade(seconds, order)
    return ct.tf(num, den)


def second_order_overshoot(pm_deg: float) -> float:
    """Step overshoot [%] of the closed loop of L = wn^2 / (s (s + 2 zeta wn)) with phase margin
    ``pm_deg`` (PM = atan(2 zeta / sqrt(sqrt(1 + 4 zeta^4) - 2 zeta^2)), solved for zeta)."""
    from scipy.optimize import brentq

    pm = math.radians(pm_deg)
    if pm <= 0.0:  # unstable closed loop
        return math.inf
    if pm >= math.radians(76.3):  # zeta >= 1: no overshoot
        return 0.0
    zeta = brentq(lambda z: math.atan(2 * z / math.sqrt(math.sqrt(1 + 4 * z**4) - 2 * z * z)) - pm, 1e-6, 0.999)
    return 100.0 * math.exp(-math.pi * zeta / math.sqrt(1 - zeta * zeta))
