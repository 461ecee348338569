"""Main-threat finder: constant-velocity closest point of approach (CPA) of each threat to the
UAV flying its straight reference (spec §9.5, G28).

Frame: local ENU z-up [m, m/s]; τ [s] from the evading instant, when the UAV is at ``start`` on
the reference and flies ``ref_vel`` along it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from avoidance.geometric.threats import ThreatArrays


@dataclass(frozen=True, slots=True)
class MainThreat:
    """The threat the candidates are built around.

    ``index`` into the threat list; ``t_cpa`` [s]; ``p_c`` (3,) the UAV's reference position at
    t_cpa (the collision point); ``miss`` [m] the threat centre's distance from p_c then;
    ``radius`` [m] of the sphere centred on the reference at p_c that encloses the threat there,
    R(t_cpa) + miss (G28)."""

    index: int
    t_cpa: float
    p_c: np.ndarray
    miss: float
    radius: float


def cpa(
    start: np.ndarray, ref_vel: np.ndarray, threats: ThreatArrays, horizon: float | np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(t_cpa (J,), miss distance (J,)) with t_cpa clipped to [0, horizon] [s] (scalar or (J,))."""
    r0 = threats.p - start
    w = threats.v - ref_vel
    ww = np.einsum("ji,ji->j", w, w)
    t = np.clip(-np.einsum("ji,ji->j", r0, w) / np.where(ww > 0, ww, 1.0), 0.0, horizon)
    return t, np.linalg.norm(r0 + w * t[:, None], axis=1)


def main_threat(
    index: int, start: np.ndarray, ref_vel: np.ndarray, threats: ThreatArrays, horizon: float
) -> MainThreat:
    """The designated threat ``index`` as main threat (its CPA with the reference)."""
    if not 0 <= index < len(threats):
        raise IndexError(f"main threat index {index} out of range for {len(threats)} threats")
    t, miss = cpa(start, ref_vel, threats, horizon)
    tc, m = float(t[index]), float(miss[index])
    r = threats.radius[index] + threats.growth[index] * tc + m
    return MainThreat(index, tc, start + ref_vel * tc, m, float(r))


def detection_horizon(
    miss: np.ndarray,
    closing: np.ndarray,
    threats: ThreatArrays,
    r_uav: float,
    min_sep_factor: float,
    ref_speed: float,
    lead_s: float,
) -> np.ndarray:
    """(J,) look-ahead [s] per threat that shows a conflict with it while candidates can still be
    built, ``lead_s`` [s] (one candidate-generation cycle) before it becomes too close.

    ``miss`` [m]: each threat's miss distance at its closest approach (CPA) to the reference up
    to its end; ``closing`` [m/s]: its speed relative to the vehicle on the reference. Made main
    threat, a threat gets the enclosing sphere R = r + miss (+ its growth over the prediction) at
    its collision point, and candidates need the evading point at least ``min_sep_factor``·R along
    the reference from it, which the vehicle covers at ``ref_speed`` v [m/s] in f·R / v. A
    look-ahead h clips the CPA time, and the miss at h is below the conflict distance
    T = r + ``r_uav`` from sqrt(T² − miss²) / closing before the CPA reaches h, so the threat is
    first seen that much earlier: h = f·R / v + lead − sqrt(T² − miss²) / closing. The lead also
    absorbs a growth of up to v·lead / f [m] over the look-ahead; larger growth is left out (a
    fresh track's velocity uncertainty would stretch the look-ahead without bound)."""
    reach = np.sqrt(np.maximum((threats.radius + r_uav) ** 2 - miss**2, 0.0))
    early = np.divide(reach, closing, out=np.zeros_like(reach), where=closing > 0)
    return min_sep_factor * (threats.radius + miss) / ref_speed + lead_s - early


def find_main_threat(
    start: np.ndarray,
    ref_vel: np.ndarray,
    threats: ThreatArrays,
    r_uav: float,
    horizon: float | np.ndarray,
    geometry_horizon: float | None = None,
) -> MainThreat | None:
    """The earliest threat whose CPA miss distance within ``horizon`` [s] (one for all, or (J,)
    per threat) is below its (grown) radius + ``r_uav`` [m]; ties broken by the smaller miss.
    None when nothing conflicts.

    The main threat's collision point and enclosing sphere come from its CPA clipped to
    ``geometry_horizon`` [s] (default ``horizon``; the planner passes the time to the reference
    end): a threat detected at the edge of the look-ahead (a static sphere whose surface is
    within reach while its centre is beyond it) would otherwise get p_c at the horizon and an
    enclosing radius swollen by the clipped miss distance."""
    if len(threats) == 0:
        return None
    t, miss = cpa(start, ref_vel, threats, horizon)
    conflict = miss < threats.radius + threats.growth * t + r_uav
    if not conflict.any():
        return None
    idx = np.flatnonzero(conflict)
    return main_threat(
        int(idx[np.lexsort((miss[idx], t[idx]))[0]]),
        start,
        ref_vel,
        threats,
        float(np.max(horizon)) if geometry_horizon is None else max(geometry_horizon, float(np.max(horizon))),
    )
