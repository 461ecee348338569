"""The encounter model: a campaign file's distributions and their seeded sampling.

Every encounter parameter (:data:`PARAMETERS`, with its unit) is fixed (a bare number, or
``{fixed = v}``) or drawn from ``{uniform = [lo, hi]}``, ``{normal = [mean, std]}`` or
``{choice = [a, b, ...]}``. Draws go through the inverse distribution function of a uniform
variate, which is either independent per encounter or, with ``latin_hypercube = true``, one per
stratum of [0, 1) for each parameter (strata in a seeded random order).
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np

# name -> (unit, default, description); angles in degrees, vertical rates positive up
PARAMETERS: dict[str, tuple[str, float, str]] = {
    "approach_angle": ("deg", 180.0, "intruder course minus ownship course (0 overtaking, 180 head-on)"),
    "own_heading": ("deg", 0.0, "ownship course from north"),
    "own_speed": ("m/s", 5.0, "ownship horizontal ground speed"),
    "intruder_speed": ("m/s", 5.0, "intruder horizontal ground speed (HAPS: true airspeed)"),
    "own_vertical_rate": ("m/s", 0.0, "ownship vertical rate, up"),
    "intruder_vertical_rate": ("m/s", 0.0, "intruder vertical rate, up"),
    "hmd": ("m", 0.0, "horizontal miss distance at the unmitigated CPA, signed: > 0 right of the relative velocity"),
    "vmd": ("m", 0.0, "vertical miss distance at the unmitigated CPA: intruder above ownship > 0"),
    "time_to_cpa": ("s", 20.0, "time from the start to the unmitigated CPA"),
    "approach_angle_2": ("deg", 120.0, "triples (intruder.count = 2): second intruder course minus ownship course"),
    "intruder_speed_2": ("m/s", 5.0, "triples: second intruder horizontal ground speed"),
    "hmd_2": ("m", 0.0, "triples: second intruder's horizontal miss distance to the ownship, signed as hmd"),
    "surveillance_noise_h": ("m", 3.0, "surveillance position noise std, horizontal"),
    "surveillance_noise_v": ("m", 5.0, "surveillance position noise std, vertical"),
    "surveillance_latency": ("s", 0.5, "surveillance report latency"),
    "surveillance_dropout": ("-", 0.05, "surveillance report dropout probability"),
    "wind_speed": ("m/s", 0.0, "steady wind speed"),
    "wind_direction": ("deg", 0.0, "direction the wind blows towards, from north"),
}


class CampaignError(ValueError):
    """The campaign file is invalid; the message names the file and the key."""


@dataclass(frozen=True, slots=True)
class Distribution:
    """One parameter's distribution: ``kind`` in fixed / uniform / normal / choice."""

    kind: str
    args: tuple[float, ...]

    @classmethod
    def parse(cls, value: object, where: str) -> Distribution:
        if isinstance(value, int | float) and not isinstance(value, bool):
            return cls("fixed", (float(value),))
        if not isinstance(value, dict) or len(value) != 1:
            raise CampaignError(f"{where}: a number or one of {{fixed, uniform, normal, choice}} = ...")
        ((kind, args),) = value.items()
        args = args if isinstance(args, list) else [args]
        if not all(isinstance(a, int | float) and not isinstance(a, bool) for a in args):
            raise CampaignError(f"{where}.{kind}: values must be numbers")
        need = {"fixed": 1, "uniform": 2, "normal": 2}
        if kind not in (*need, "choice"):
            raise CampaignError(f"{where}: unknown distribution {kind!r} (fixed, uniform, normal, choice)")
        if kind in need and len(args) != need[kind]:
            raise CampaignError(f"{where}.{kind}: needs {need[kind]} value(s), got {len(args)}")
        if kind == "choice" and not args:
            raise CampaignError(f"{where}.choice: needs at least one value")
        if kind == "uniform" and args[1] < args[0]:
            raise CampaignError(f"{where}.uniform: [lo, hi] with lo <= hi, got {args}")
        if kind == "normal" and args[1] < 0:
            raise CampaignError(f"{where}.normal: standard deviation must be >= 0, got {args[1]}")
        return cls(kind, tuple(float(a) for a in args))

    def quantile(self, u: np.ndarray) -> np.ndarray:
        """Values at the uniform variates ``u`` in [0, 1) (inverse distribution function)."""
        a = self.args
        if self.kind == "fixed":
            return np.full(len(u), a[0])
        if self.kind == "uniform":
            return a[0] + u * (a[1] - a[0])
        if self.kind == "choice":
            return np.asarray(a)[np.minimum((u * len(a)).astype(int), len(a) - 1)]
        nd = NormalDist(a[0], a[1]) if a[1] > 0 else None
        return np.array([nd.inv_cdf(min(max(x, 1e-12), 1 - 1e-12)) if nd else a[0] for x in u])


def parse_distributions(table: dict, where: str) -> dict[str, Distribution]:
    """Every parameter's distribution: the table's entries over the defaults (fixed)."""
    unknown = sorted(set(table) - set(PARAMETERS))
    if unknown:
        raise CampaignError(f"{where}.{unknown[0]}: unknown parameter (known: {', '.join(PARAMETERS)})")
    out = {k: Distribution("fixed", (d,)) for k, (_, d, _) in PARAMETERS.items()}
    out |= {k: Distribution.parse(v, f"{where}.{k}") for k, v in table.items()}
    return out


def sample(dists: dict[str, Distribution], n: int, seed: int, latin_hypercube: bool = False) -> list[dict[str, float]]:
    """``n`` parameter sets, reproducible from ``seed``; each parameter has its own stream, so
    adding a parameter leaves the others' draws unchanged."""
    cols: dict[str, np.ndarray] = {}
    for name in dists:
        rng = np.random.default_rng([seed, zlib.crc32(name.encode())])
        u = rng.random(n)
        if latin_hypercube:
            u = (rng.permutation(n) + u) / n
        cols[name] = dists[name].quantile(u)
    return [{name: float(cols[name][i]) for name in dists} for i in range(n)]


def wrap_deg(angle: float) -> float:
    """Angle in [0, 360) [deg]."""
    return math.fmod(math.fmod(angle, 360.0) + 360.0, 360.0)
