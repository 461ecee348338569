"""Campaign statistics over paired encounters (each flown mitigated and unmitigated).

Risk ratio = P(NMAC | mitigated) / P(NMAC | unmitigated) (RTCA DO-365 style), with a 95 %
interval by MOVER-R (Zou & Donner 2008, ratio of two proportions from their Wilson score
intervals; the pairing is ignored, which widens the interval). Induced NMAC: an encounter safe
unmitigated and an NMAC mitigated. Extra path length: the mitigated ownship's mission path minus
its planned straight leg [m]; minimum separation: the mitigated run's closest horizontal pass [m].
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Callable, Iterable
from dataclasses import dataclass

Z95 = 1.959963984540054  # two-sided 95 % normal quantile
_STATS: dict[str, Callable[[list[float]], float]] = {"mean": statistics.fmean, "median": statistics.median, "min": min}


def wilson(k: int, n: int, z: float = Z95) -> tuple[float, float]:
    """Wilson score interval of a proportion ``k / n`` (n > 0)."""
    if n <= 0:
        raise ValueError("wilson: n must be > 0")
    p = k / n
    den = 1 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return max(0.0, mid - half), min(1.0, mid + half)


def ratio_interval(k1: int, n1: int, k2: int, n2: int, z: float = Z95) -> tuple[float, float] | None:
    """MOVER-R 95 % interval of (k1/n1) / (k2/n2) from the Wilson intervals; None when k2 = 0
    (the ratio is undefined)."""
    if k2 == 0:
        return None
    p1, p2 = k1 / n1, k2 / n2
    l1, u1 = wilson(k1, n1, z)
    l2, u2 = wilson(k2, n2, z)
    lo_rad = (p1 * p2) ** 2 - l1 * u2 * (2 * p1 - l1) * (2 * p2 - u2)
    hi_rad = (p1 * p2) ** 2 - u1 * l2 * (2 * p1 - u1) * (2 * p2 - l2)
    lo = (p1 * p2 - math.sqrt(max(lo_rad, 0.0))) / (u2 * (2 * p2 - u2))
    hi = (p1 * p2 + math.sqrt(max(hi_rad, 0.0))) / (l2 * (2 * p2 - l2)) if l2 > 0 else math.inf
    return (lo if lo > 0.0 else 0.0), hi


@dataclass(frozen=True, slots=True)
class Pair:
    """One encounter's outcome in both modes (failed runs excluded before)."""

    nmac_mitigated: bool
    nmac_unmitigated: bool
    lowc_mitigated: bool
    lowc_unmitigated: bool
    complete_mitigated: bool
    geometry: dict[str, str]  # bin name -> bin label
    extra_path_m: float | None = None  # mitigated ownship path minus its planned straight leg [m]
    min_separation_m: float | None = None  # mitigated closest horizontal separation [m]


def summarise(pairs: list[Pair]) -> dict:
    """n, NMAC counts, risk ratio and its interval, LoWC ratio, induced NMACs, completion rate,
    extra path length (mean, median) and minimum separation (smallest, median) where known."""
    n = len(pairs)
    if n == 0:
        return {"n": 0}
    nm = sum(p.nmac_mitigated for p in pairs)
    nu = sum(p.nmac_unmitigated for p in pairs)
    lm = sum(p.lowc_mitigated for p in pairs)
    lu = sum(p.lowc_unmitigated for p in pairs)
    ci = ratio_interval(nm, n, nu, n)
    return {
        "n": n,
        "nmac_mitigated": nm,
        "nmac_unmitigated": nu,
        "risk_ratio": nm / nu if nu else None,
        "risk_ratio_ci95": list(ci) if ci is not None else None,
        "lowc_mitigated": lm,
        "lowc_unmitigated": lu,
        "lowc_ratio": lm / lu if lu else None,
        "induced_nmac": sum(p.nmac_mitigated and not p.nmac_unmitigated for p in pairs),
        "completion_rate": sum(p.complete_mitigated for p in pairs) / n,
        **_spread("extra_path_m", [p.extra_path_m for p in pairs], ("mean", "median")),
        **_spread("min_separation_m", [p.min_separation_m for p in pairs], ("min", "median")),
    }


def _spread(name: str, values: list[float | None], stats: tuple[str, ...]) -> dict[str, float]:
    """``{name_stat: value}`` of the known ``values`` (none known: empty)."""
    known = [v for v in values if v is not None]
    if not known:
        return {}
    return {f"{name}_{s}": float(_STATS[s](known)) for s in stats}


def by_bin(pairs: list[Pair]) -> dict[str, dict[str, dict]]:
    """:func:`summarise` per geometry bin: {bin name: {label: summary}}."""
    names = sorted({k for p in pairs for k in p.geometry})
    return {
        name: {
            label: summarise([p for p in pairs if p.geometry.get(name) == label])
            for label in sorted({p.geometry[name] for p in pairs if name in p.geometry})
        }
        for name in names
    }


def _labeller(edges: Iterable[float], labels: Iterable[str]) -> Callable[[float], str]:
    edges, labels = list(edges), list(labels)

    def label(x: float) -> str:
        for e, lab in zip(edges, labels, strict=False):
            if x < e:
                return lab
        return labels[-1]

    return label


_APPROACH = _labeller([22.5, 67.5, 112.5, 157.5, 202.5, 247.5, 292.5, 337.5], [
    "000 overtaking", "045 converging", "090 crossing", "135 converging", "180 head-on",
    "225 converging", "270 crossing", "315 converging", "000 overtaking"])  # fmt: skip
_SPEED = _labeller([0.75, 1.33], ["intruder slower", "similar", "intruder faster"])


def geometry_bins(p: dict[str, float]) -> dict[str, str]:
    """Bins of an encounter's parameters: approach angle (45° sectors), vertical geometry (level /
    the ownship or the intruder climbing or descending), speed ratio intruder/ownship."""
    own_vz, int_vz = p["own_vertical_rate"], p["intruder_vertical_rate"]
    vertical = "level" if max(abs(own_vz), abs(int_vz)) < 0.25 else "vertical rates"
    ratio = p["intruder_speed"] / p["own_speed"] if p["own_speed"] > 0 else math.inf
    return {"approach": _APPROACH(p["approach_angle"] % 360.0), "vertical": vertical, "speed_ratio": _SPEED(ratio)}
