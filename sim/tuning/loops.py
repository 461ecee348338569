"""Loop analysis shared by every controller loop: margins and closed-loop figures, delays.

Margins from ``control.stability_margins`` (gain margin [dB], phase margin [deg], their
frequencies [rad/s]); bandwidth of the closed loop (-3 dB) [rad/s]; step info of the closed loop
(overshoot [%], 10-90 % rise time [s], 2 % settling time [s]) over a given record, as
:class:`StepResponse` computes them for the JSBSim steps. The loops themselves are built in
:mod:`sim.tuning.loops_haps` and :mod:`sim.tuning.loops_quad`; :mod:`sim.tuning.catalog` lists
them per airframe.
"""

from __future__ import annotations

import math
from collections.abc import Callable
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


@dataclass(frozen=True)
class StepResponse:
    """Response ``y`` (minus its pre-step value) at times ``t`` [s] to a step of size ``step``."""

    t: np.ndarray
    y: np.ndarray
    step: float

    @property
    def overshoot_pct(self) -> float:
        """(peak - step) / step [%], 0 when the response stays below the step."""
        return max(0.0, 100.0 * (float(np.max(self.y / self.step)) - 1.0))

    def settling_time_s(self, band: float = 0.02) -> float:
        """Time [s] after which the response stays within ``band`` x step of the step (NaN when
        it is still outside at the end of the record)."""
        out = np.abs(self.y / self.step - 1.0) > band
        if out[-1]:
            return math.nan
        k = np.flatnonzero(out)
        return float(self.t[k[-1] + 1]) if k.size else float(self.t[0])

    @property
    def rise_time_s(self) -> float:
        """10-90 % rise time [s] (NaN when the response never reaches 90 %)."""
        r = self.y / self.step
        hi = np.flatnonzero(r >= 0.9)
        if not hi.size:
            return math.nan
        return float(self.t[hi[0]] - self.t[np.flatnonzero(r >= 0.1)[0]])

    @property
    def final_ratio(self) -> float:
        """Last sample over the step."""
        return float(self.y[-1] / self.step)


def analyse(name: str, L, T, seconds: float, drive: Callable[[np.ndarray], np.ndarray] | None = None) -> LoopReport:
    """Margins of open loop ``L``, bandwidth of closed loop ``T`` and its response figures over
    ``seconds`` (the same figures and record length as the loop's JSBSim step): to a unit step,
    or to the inputs ``drive(t)`` [n_inputs x len(t)] that end at a unit change of the output
    (bandwidth then NaN: T has several inputs)."""
    with np.errstate(over="ignore"):  # the order-46 TECS loops overflow a polynomial at high frequency
        gm, pm, _, wpc, wgc, _ = ct.stability_margins(L)  # (same margins as from their frequency response)
    t = np.linspace(0.0, seconds, 4001)
    resp = ct.step_response(T, t) if drive is None else ct.forced_response(T, t, drive(t))
    st = StepResponse(t, np.asarray(resp.outputs, float).reshape(-1), 1.0)
    return LoopReport(
        name,
        float(wgc),
        float(pm),
        20 * math.log10(gm) if np.isfinite(gm) and gm > 0 else math.inf,
        float(wpc),
        float(ct.bandwidth(T)) if drive is None else math.nan,
        st.overshoot_pct,
        st.rise_time_s,
        st.settling_time_s(),
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
