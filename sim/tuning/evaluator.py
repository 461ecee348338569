"""JSBSim as a function: body state + property inputs -> state derivatives, without time stepping.

State vector (SI, body FRD axes, Euler 3-2-1 angles, ISA altitude MSL)::

    x = [u, v, w, p, q, r, phi, theta, psi, h]     [m/s, m/s, m/s, rad/s x3, rad x3, m]

The state is written through JSBSim's ``ic/*`` properties (attitude first: JSBSim keeps the NED
velocity when the attitude changes) and ``run_ic()`` evaluates every model once with integration
suspended, so ``accelerations/*`` hold f(x, u). Two evaluations per call make the alpha-rate terms
(CL_alphadot, Cm_alphadot: JSBSim takes alpha-dot from the previous frame's accelerations)
consistent with the accelerations: a fixed point, reached to < 1e-6 after the second pass.

Engines: ``run_ic`` keeps propeller speeds as they are. :meth:`JSBSimEvaluator.settle_engines`
brings them to steady state at the current state and throttles by stepping JSBSim while putting
the state back before every step (only the engine states advance). Linearisation keeps the
propeller speed at its trim value (a slow state: ~3 s for the HAPS).
"""

from __future__ import annotations

import math

import numpy as np

from sim.core.constants import FT
from sim.jsbsim_plant import JSBSimPlant

STATE_NAMES = ("u", "v", "w", "p", "q", "r", "phi", "theta", "psi", "h")
STATE_UNITS = ("m/s", "m/s", "m/s", "rad/s", "rad/s", "rad/s", "rad", "rad", "rad", "m")

_ACC = (
    "accelerations/udot-ft_sec2",
    "accelerations/vdot-ft_sec2",
    "accelerations/wdot-ft_sec2",
    "accelerations/pdot-rad_sec2",
    "accelerations/qdot-rad_sec2",
    "accelerations/rdot-rad_sec2",
)


def euler_rates(p: float, q: float, r: float, phi: float, theta: float) -> tuple[float, float, float]:
    """Euler-angle rates (phi_dot, theta_dot, psi_dot) [rad/s] from body rates [rad/s]."""
    sp, cp, ct, tt = math.sin(phi), math.cos(phi), math.cos(theta), math.tan(theta)
    return (p + (q * sp + r * cp) * tt, q * cp - r * sp, (q * sp + r * cp) / ct)


def climb_rate(x: np.ndarray) -> float:
    """dh/dt [m/s] of state ``x`` (flat earth, no wind)."""
    u, v, w, _, _, _, phi, theta = x[:8]
    return u * math.sin(theta) - v * math.sin(phi) * math.cos(theta) - w * math.cos(phi) * math.cos(theta)


class JSBSimEvaluator:
    """f(x, inputs) of a loaded :class:`JSBSimPlant` (its lat/lon stay where they are)."""

    def __init__(self, plant: JSBSimPlant):
        self.plant = plant
        self.fdm = plant.fdm

    def read_state(self) -> np.ndarray:
        """The plant's current state as ``x`` (SI)."""
        f = self.fdm
        return np.array(
            [
                f["velocities/u-fps"] * FT,
                f["velocities/v-fps"] * FT,
                f["velocities/w-fps"] * FT,
                f["velocities/p-rad_sec"],
                f["velocities/q-rad_sec"],
                f["velocities/r-rad_sec"],
                f["attitude/phi-rad"],
                f["attitude/theta-rad"],
                f["attitude/psi-rad"],
                f["position/h-sl-ft"] * FT,
            ]
        )

    def set_state(self, x: np.ndarray, inputs: dict[str, float] | None = None) -> None:
        """Write ``x`` and the input properties, evaluate all models once (twice: alpha-dot)."""
        f = self.fdm
        lat, lon = f["position/lat-geod-deg"], f["position/long-gc-deg"]
        for k, v in (inputs or {}).items():
            f[k] = float(v)
        f["ic/lat-geod-deg"] = lat
        f["ic/long-gc-deg"] = lon
        f["ic/h-sl-ft"] = x[9] / FT
        f["ic/phi-rad"] = x[6]
        f["ic/theta-rad"] = x[7]
        f["ic/psi-true-rad"] = x[8] % math.tau
        f["ic/u-fps"] = x[0] / FT
        f["ic/v-fps"] = x[1] / FT
        f["ic/w-fps"] = x[2] / FT
        f["ic/p-rad_sec"] = x[3]
        f["ic/q-rad_sec"] = x[4]
        f["ic/r-rad_sec"] = x[5]
        f.run_ic()
        f.run_ic()

    def derivatives(self, x: np.ndarray, inputs: dict[str, float] | None = None) -> np.ndarray:
        """dx/dt at ``x`` with ``inputs`` (property -> value), SI, same order as ``x``."""
        self.set_state(x, inputs)
        return self.read_derivatives(x)

    def read_derivatives(self, x: np.ndarray) -> np.ndarray:
        """dx/dt of the last evaluated state ``x``."""
        f = self.fdm
        a = [f[k] for k in _ACC]
        dphi, dth, dpsi = euler_rates(x[3], x[4], x[5], x[6], x[7])
        return np.array([a[0] * FT, a[1] * FT, a[2] * FT, a[3], a[4], a[5], dphi, dth, dpsi, climb_rate(x)])

    def settle_engines(
        self,
        x: np.ndarray,
        inputs: dict[str, float] | None = None,
        max_steps: int = 20_000,
        rtol: float = 1e-10,
        trace: str | None = None,
    ) -> tuple[int, list[float]]:
        """Step only the engines to steady state at ``x`` (state restored before every step).

        Converged when every propeller speed changes by less than ``rtol`` (relative) per step
        for 20 steps. Returns (steps taken, ``trace`` property sampled after every step).
        Raises RuntimeError if not converged within ``max_steps``.
        """
        f = self.fdm
        n = self.plant.engine_count
        names = [f"propulsion/engine[{i}]/propeller-rpm" for i in range(n)]
        calm, samples = 0, []
        self.set_state(x, inputs)
        for k in range(1, max_steps + 1):
            before = [f[p] for p in names]
            f.run()
            if trace:
                samples.append(f[trace])
            after = [f[p] for p in names]
            self.set_state(x)
            ok = all(abs(a - b) <= rtol * max(abs(a), 1.0) for a, b in zip(after, before, strict=False))
            calm = calm + 1 if ok else 0
            if calm >= 20:
                return k, samples
        raise RuntimeError(f"engines did not settle in {max_steps} steps (rpm {[round(f[p], 1) for p in names]})")
