"""Normalisation of cost terms to [0, 1] and cap calibration (spec §5.7, G1, G2, G20).

Time [s] and energy [J]: clip to [lo, hi] then min-max. Smoothness, S_rp and CMO (right-skewed,
dimensionless): natural log, clip, min-max; a value of 0 (e.g. M without moving threats) maps to 0.
"""

from __future__ import annotations

import numpy as np

from avoidance.geometric.config import CostCaps


def clip_minmax(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """(clip(x, lo, hi) − lo) / (hi − lo) (eqs 4.28–4.29)."""
    return (np.clip(x, lo, hi) - lo) / (hi - lo)


def log_clip_minmax(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """clip_minmax(ln x, lo, hi) for x > 0, 0 for x <= 0 (eqs 4.30–4.32 with ln, G1/G2)."""
    x = np.asarray(x, float)
    with np.errstate(divide="ignore"):
        lx = np.log(np.where(x > 0, x, 1.0))
    return np.where(x > 0, clip_minmax(lx, lo, hi), 0.0)


def caps_from_samples(
    time_s: np.ndarray, energy_j: np.ndarray, upper_quantile: float = 0.995, time_factor: float = 1.15
) -> CostCaps:
    """Caps from a sweep of collision-free candidates: lower = minimum, upper = the
    ``upper_quantile`` value, time upper × ``time_factor`` (G20)."""
    time_s, energy_j = np.asarray(time_s, float), np.asarray(energy_j, float)
    if time_s.size == 0 or energy_j.size == 0:
        raise ValueError("cap calibration needs at least one sample")
    return CostCaps(
        time_lo=float(time_s.min()),
        time_hi=float(np.quantile(time_s, upper_quantile) * time_factor),
        energy_lo=float(energy_j.min()),
        energy_hi=float(np.quantile(energy_j, upper_quantile)),
    )
