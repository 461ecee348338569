"""Gain proposal for any loop of :mod:`sim.tuning.catalog`, and its verification in JSBSim.

A loop's gains are scaled together by one factor k, so its open loop is k L1(s) with L1 the loop
at the current gains (the loop is opened where all of them act). One request fixes k:

- crossover wc [rad/s]:  k = 1 / |L1(j wc)|; the phase margin is then 180 deg - |arg L1(j wc)|;
- phase margin PM [deg]: wc is the highest frequency where 180 deg - |arg L1(j w)| = PM, then k
  as above.

Reachable: crossovers where the closed loop of k L1 is stable and that phase margin positive,
from a tenth of the loop's crossover at the given gains (a slower loop leaves the plant's own
slow modes, e.g. the HAPS spiral and phugoid, to set the response: scaling gains is not the tool
there) to the loop's ``max_crossover_rad_s`` (a tenth of its sample frequency, where the
half-step delay still stands for the zero-order hold); the contiguous band of a log grid of 1e-3..1e3 rad/s
that holds the loop's own crossover (or the widest one). Phase margins: those met at a
crossover in that band. Anything else is a ValueError
naming the loop and the reachable range. A proposal under ``LOW_MARGIN_DEG`` carries a warning.

Verification: the proposed gains fly the loop's JSBSim step (:mod:`sim.tuning.steps`); its
overshoot and settling time are reported beside the linear closed loop's and the second-order
estimate from the phase margin.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import control as ct
import numpy as np

from sim.tuning.catalog import Loop, file_key, gain_value, scaled
from sim.tuning.loops import LoopReport, second_order_overshoot

LOW_MARGIN_DEG = 30.0
MIN_CROSSOVER_RATIO = 0.1  # lowest crossover searched, per the loop's crossover at the given gains
_GRID = np.geomspace(1e-3, 1e3, 6001)  # [rad/s]


@dataclass
class Proposal:
    """Proposed gains (``gains.toml`` keys -> values), the request, the linear figures and,
    after :func:`verify_in_jsbsim`, the JSBSim step's; ``warnings`` one line each."""

    airframe: str
    loop: str
    request: dict[str, float]
    factor: float
    gains: dict[str, float]
    linear: LoopReport
    second_order_overshoot_pct: float
    new_gains: Any = field(repr=False, default=None)
    jsbsim_overshoot_pct: float | None = None
    jsbsim_settling_time_s: float | None = None
    warnings: list[str] = field(default_factory=list)

    def row(self) -> dict:
        """JSON-ready record (the proposal file)."""
        return {
            "airframe": self.airframe,
            "loop": self.loop,
            "request": self.request,
            "factor": self.factor,
            "gains": self.gains,
            "linear": self.linear.row(),
            "second_order_overshoot_pct": self.second_order_overshoot_pct,
            "jsbsim_overshoot_pct": self.jsbsim_overshoot_pct,
            "jsbsim_settling_time_s": self.jsbsim_settling_time_s,
            "warnings": self.warnings,
        }


def _margin_deg(l1) -> np.ndarray:
    """Phase margin [deg] that a crossover at each grid frequency would have: the angle between
    L1(jw) and -1, 180 - |arg L1| (its sign, i.e. stability, is judged by the closed-loop poles)."""
    return 180.0 - np.abs(np.degrees(np.angle(np.asarray(l1(1j * _GRID), complex))))


def _closed_loop_stable(l1) -> np.ndarray:
    """Per grid frequency: is the closed loop of k L1 stable with k putting the crossover there
    (roots of den + k num in the open left half-plane)? Checked on every 10th grid point."""
    num, den = (np.atleast_1d(np.squeeze(a)) for a in ct.tfdata(ct.tf(l1)))
    mag = np.abs(np.asarray(l1(1j * _GRID), complex))
    stable = np.zeros(_GRID.size, bool)
    for k in range(0, _GRID.size, 10):
        poly = np.polyadd(den, num / mag[k])
        stable[k : k + 10] = bool(np.all(np.roots(poly).real < 0))
    return stable


def _stable_band(pm: np.ndarray, stable: np.ndarray, own_wc: float) -> tuple[int, int]:
    """First and last grid index of the band where the phase margin would be positive and the
    closed loop stable."""
    good = (pm > 0) & stable
    edges = np.flatnonzero(np.diff(np.concatenate(([0], good.astype(int), [0]))))
    bands = list(zip(edges[::2], edges[1::2] - 1, strict=True))
    if not bands:
        return 0, -1
    for lo, hi in bands:
        if _GRID[lo] <= own_wc <= _GRID[hi]:
            return int(lo), int(hi)
    lo, hi = max(bands, key=lambda b: b[1] - b[0])
    return int(lo), int(hi)


def _band(loop: Loop, l1) -> tuple[np.ndarray, np.ndarray]:
    """Grid indices of the reachable crossover band and the phase margin [deg] at every grid point."""
    pm = _margin_deg(l1)
    _, _, _, _, own_wc, _ = ct.stability_margins(l1)
    ok = _closed_loop_stable(l1) & (loop.max_crossover_rad_s >= _GRID) & (MIN_CROSSOVER_RATIO * own_wc <= _GRID)
    lo, hi = _stable_band(pm, ok, float(own_wc))
    if hi < lo:
        raise ValueError(f"{loop.airframe} {loop.name} loop: no crossover gives a stable closed loop")
    return np.arange(lo, hi + 1), pm


def reachable(loop: Loop, gains: Any) -> tuple[float, float, float, float]:
    """(lowest, highest crossover [rad/s], smallest, largest phase margin [deg]) reachable by
    scaling the loop's gains (module docstring)."""
    band, pm = _band(loop, loop.build(gains)[0])
    return float(_GRID[band[0]]), float(_GRID[band[-1]]), float(pm[band].min()), float(pm[band].max())


def _range_text(band: np.ndarray, pm: np.ndarray) -> str:
    hi = f"{_GRID[band[-1]]:.3g} rad/s"
    w = f"{_GRID[band[0]]:.3g}-{hi}" if band[0] > 0 else f"up to {hi}"
    return f"reachable: crossover {w}, phase margin {pm[band].min():.1f}-{pm[band].max():.1f} deg"


def propose(
    loop: Loop, gains: Any, crossover_rad_s: float | None = None, phase_margin_deg: float | None = None
) -> Proposal:
    """Gains of ``loop`` scaled for a requested crossover *or* phase margin; ValueError with the
    reachable range when the request cannot be met."""
    if (crossover_rad_s is None) == (phase_margin_deg is None):
        raise ValueError("give exactly one of a crossover and a phase margin")
    if not loop.tunable:
        raise ValueError(
            f"{loop.airframe} {loop.name} loop: not tunable by one factor (its demand terms close the loop "
            "too); its margins: cosim tune margins"
        )
    l1, _ = loop.build(gains)
    band, pm = _band(loop, l1)
    what = f"{loop.airframe} {loop.name} loop"
    if crossover_rad_s is not None:
        request = {"crossover_rad_s": crossover_rad_s}
        if not _GRID[band[0]] <= crossover_rad_s <= _GRID[band[-1]]:
            raise ValueError(f"{what}: crossover {crossover_rad_s:g} rad/s unreachable; {_range_text(band, pm)}")
        w_c = crossover_rad_s
    else:
        assert phase_margin_deg is not None
        request = {"phase_margin_deg": phase_margin_deg}
        d = pm[band] - phase_margin_deg
        cross = np.flatnonzero(d[:-1] * d[1:] <= 0)
        if not cross.size:
            raise ValueError(f"{what}: phase margin {phase_margin_deg:g} deg unreachable; {_range_text(band, pm)}")
        k = int(cross[-1])  # the highest crossover with the requested margin
        f = d[k] / (d[k] - d[k + 1]) if d[k] != d[k + 1] else 0.0
        w_c = float(_GRID[band[k]] * (_GRID[band[k + 1]] / _GRID[band[k]]) ** f)
    factor = 1.0 / abs(complex(l1(1j * w_c)))
    new = scaled(gains, loop.gains, factor)
    if np.any(ct.poles(loop.build(new)[1]).real >= 0):  # the grid's stability sampling missed it
        raise ValueError(f"{what}: the closed loop at crossover {w_c:.3g} rad/s is unstable; {_range_text(band, pm)}")
    rep = loop.analyse(new)
    p = Proposal(
        loop.airframe,
        loop.name,
        request,
        factor,
        {file_key(loop.airframe, g): gain_value(new, g) for g in loop.gains},
        rep,
        second_order_overshoot(rep.phase_margin_deg),
        new,
    )
    if rep.phase_margin_deg < LOW_MARGIN_DEG:
        p.warnings.append(
            f"phase margin {rep.phase_margin_deg:.1f} deg is under {LOW_MARGIN_DEG:.0f} deg: expect a large overshoot "
            f"(second-order estimate {p.second_order_overshoot_pct:.0f} %) and little robustness to delay"
        )
    return p


def verify_in_jsbsim(loop: Loop, p: Proposal) -> Proposal:
    """Fly the loop's JSBSim step with the proposed gains; fills the JSBSim fields."""
    r = loop.step(p.new_gains)
    p.jsbsim_overshoot_pct = r.overshoot_pct
    p.jsbsim_settling_time_s = r.settling_time_s()
    return p
