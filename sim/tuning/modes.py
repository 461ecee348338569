"""Classical aircraft modes from the longitudinal and lateral-directional A matrices.

Longitudinal states [u, w, q, theta]: two oscillatory pairs, the faster is the short period, the
slower the phugoid. Lateral [v, p, r, phi]: the oscillatory pair is the Dutch roll, the fastest
real root the roll subsidence, the slowest real root the spiral (unstable if positive).
Reported per mode: eigenvalue [1/s], natural frequency [rad/s], damping ratio, period [s]
(oscillatory) or time constant [s] (stable real) / time to double [s] (unstable real).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.tuning.linearize import LATERAL, LONGITUDINAL, LinearModel


@dataclass(frozen=True)
class Mode:
    name: str
    eigenvalue: complex
    wn_rad_s: float
    zeta: float
    period_s: float  # NaN for real roots
    time_const_s: float  # 1/|Re| for a stable real root; NaN otherwise
    time_to_double_s: float  # ln 2 / Re for an unstable root; NaN otherwise

    def row(self) -> dict:
        ev = self.eigenvalue
        return {
            "mode": self.name,
            "eig_re": ev.real,
            "eig_im": abs(ev.imag),
            "wn_rad_s": self.wn_rad_s,
            "zeta": self.zeta,
            "period_s": self.period_s,
            "time_const_s": self.time_const_s,
            "time_to_double_s": self.time_to_double_s,
        }


def _mode(name: str, ev: complex) -> Mode:
    wn = abs(ev)
    zeta = -ev.real / wn if wn > 0 else math.nan
    period = 2 * math.pi / abs(ev.imag) if abs(ev.imag) > 1e-9 else math.nan
    tc = 1.0 / -ev.real if (abs(ev.imag) <= 1e-9 and ev.real < 0) else math.nan
    t2 = math.log(2) / ev.real if ev.real > 0 else math.nan
    return Mode(name, complex(ev), wn, zeta, period, tc, t2)


def longitudinal_modes(lm: LinearModel) -> list[Mode]:
    a, _ = lm.sub(LONGITUDINAL)
    ev = np.linalg.eigvals(a)
    osc = sorted([e for e in ev if e.imag > 1e-9], key=abs, reverse=True)
    if len(osc) != 2:
        raise ValueError(f"expected two oscillatory longitudinal pairs, got eigenvalues {ev}")
    return [_mode("short period", osc[0]), _mode("phugoid", osc[1])]


def lateral_modes(lm: LinearModel) -> list[Mode]:
    a, _ = lm.sub(LATERAL)
    ev = np.linalg.eigvals(a)
    osc = [e for e in ev if e.imag > 1e-9]
    real = sorted([e.real for e in ev if abs(e.imag) <= 1e-9])
    if len(osc) != 1 or len(real) != 2:
        raise ValueError(f"expected one oscillatory and two real lateral roots, got {ev}")
    return [_mode("roll subsidence", complex(real[0])), _mode("Dutch roll", osc[0]), _mode("spiral", complex(real[1]))]


def all_modes(lm: LinearModel) -> list[Mode]:
    return longitudinal_modes(lm) + lateral_modes(lm)
