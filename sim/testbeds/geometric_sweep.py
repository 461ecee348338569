"""The thesis cost-study sweep (spec §7.1, Table 4.1, G20–G23) used to recalibrate the time and
energy caps for a vehicle (``scripts/geometric_caps_sweep.py``).

Environment IDs (0-based, reconstructed; they reproduce the thesis' #1440 and #11088):
``id = 3240·i_DM + 360·i_EM + 72·i_SM + 24·i_Dm + 3·i_Em + i_Sm``.
Geometry in local ENU z-up [m]: UAV at the origin flying towards a static main threat at
(D_M, 0, E_M) of radius S_M; one moving threat at (D_m, 0, E_m), radius S_m, velocity (0, 2, 0) m/s.
"""

from __future__ import annotations

import numpy as np

from avoidance.geometric.avoider import RAW_TERMS
from avoidance.geometric.config import GeometricConfig, VehicleParams
from avoidance.geometric.threats import Threat
from sim.testbeds.geometric_encounters import Encounter

D_MAIN = 3.0 + 1.75 * np.arange(5)
E_MAIN = -7.0 + 1.75 * np.arange(9)
S_MAIN = 1.0 + 0.5 * np.arange(5)
D_MOVING = 3.0 + 3.5 * np.arange(3)
E_MOVING = np.linspace(-10.0, 10.0, 8)
S_MOVING = 1.0 + 0.5 * np.arange(3)
AXES = (D_MAIN, E_MAIN, S_MAIN, D_MOVING, E_MOVING, S_MOVING)
N_ENVIRONMENTS = int(np.prod([len(a) for a in AXES]))  # 16 200
MOVING_VELOCITY = np.array([0.0, 2.0, 0.0])
LOWER_CAP_ENV, UPPER_CAP_ENV = 1440, 11088


def env_index(env_id: int) -> tuple[int, ...]:
    """(i_DM, i_EM, i_SM, i_Dm, i_Em, i_Sm) of an environment ID."""
    if not 0 <= env_id < N_ENVIRONMENTS:
        raise ValueError(f"environment ID must be in [0, {N_ENVIRONMENTS}), got {env_id}")
    return tuple(int(i) for i in np.unravel_index(env_id, [len(a) for a in AXES]))


def env_id(indices: tuple[int, ...]) -> int:
    """Inverse of :func:`env_index`."""
    return int(np.ravel_multi_index(indices, [len(a) for a in AXES]))


def env_params(env: int) -> dict[str, float]:
    """Table 4.1 values of an environment: D_M, E_M, S_M, D_m, E_m, S_m [m]."""
    return {
        k: float(a[i])
        for k, a, i in zip(("D_M", "E_M", "S_M", "D_m", "E_m", "S_m"), AXES, env_index(env), strict=False)
    }


def sweep_encounter(env: int) -> Encounter:
    p = env_params(env)
    main = np.array([p["D_M"], 0.0, p["E_M"]])
    return Encounter(
        np.zeros(3),
        main,
        (
            Threat("main", main, np.zeros(3), p["S_M"]),
            Threat("moving", np.array([p["D_m"], 0.0, p["E_m"]]), MOVING_VELOCITY, p["S_m"]),
        ),
    )


def sweep_config(**overrides) -> GeometricConfig:
    """The sweep's planner setup: thesis checks, l = 12, planes 0°–165° (n = 11), both types."""
    return GeometricConfig.thesis(**{"l": 12, "n_planes": 11, "path_types": ("simple", "symmetric"), **overrides})


def run_sweep(envs, cfg: GeometricConfig, veh: VehicleParams) -> dict[str, np.ndarray]:
    """Raw cost terms of every collision-free candidate over ``envs`` (IDs), plus ``env`` and
    ``candidate`` indices of each sample. Environments that are too close yield nothing."""
    out: dict[str, list[np.ndarray]] = {k: [] for k in (*RAW_TERMS, "env", "candidate")}
    for e in envs:
        res = sweep_encounter(int(e)).plan(cfg, veh)
        if res.available is None or res.costs is None:  # too close: nothing evaluated
            continue
        idx = np.flatnonzero(res.available)
        for k in RAW_TERMS:
            out[k].append(res.costs.raw[k][idx])
        out["env"].append(np.full(idx.size, int(e)))
        out["candidate"].append(idx)
    return {k: np.concatenate(v) if v else np.zeros(0) for k, v in out.items()}
