"""Numerical linearisation of a JSBSim model about a trim point: dx/dt = A dx + B du.

Central differences of :meth:`JSBSimEvaluator.derivatives` (every JSBSim model evaluated, FCS
included, with integration suspended). States: ``sim.tuning.evaluator.STATE_NAMES`` (body
velocities, body rates, Euler angles, altitude; SI). Inputs: JSBSim properties (for the HAPS the
normalised pilot surface commands and the two throttles). Propeller speeds stay at their trim
values (they are slow states, ~3 s on the HAPS, and not part of x).

Perturbations: 0.01 m/s, 1e-4 rad/s, 1e-4 rad, 0.1 m; inputs 1e-3 (normalised). The HAPS tables
are piecewise linear in alpha, so the central differences are exact within one table segment.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sim.tuning.evaluator import STATE_NAMES, STATE_UNITS, JSBSimEvaluator

STATE_STEPS = np.array([0.01, 0.01, 0.01, 1e-4, 1e-4, 1e-4, 1e-4, 1e-4, 1e-4, 0.1])
HAPS_INPUTS = ("fcs/elevator-cmd-norm", "fcs/aileron-cmd-norm", "fcs/rudder-cmd-norm", "throttle")
_THROTTLE_PROPS = ("fcs/throttle-cmd-norm[0]", "fcs/throttle-cmd-norm[1]")

LONGITUDINAL = ("u", "w", "q", "theta")
LATERAL = ("v", "p", "r", "phi")


@dataclass
class LinearModel:
    """Continuous-time A [n x n], B [n x m] about (x0, u0); names and units of x and u."""

    A: np.ndarray
    B: np.ndarray
    x0: np.ndarray
    u0: np.ndarray
    states: tuple[str, ...] = STATE_NAMES
    inputs: tuple[str, ...] = HAPS_INPUTS
    state_units: tuple[str, ...] = STATE_UNITS
    trim: dict = field(default_factory=dict)

    def sub(self, states, inputs=None) -> tuple[np.ndarray, np.ndarray]:
        """(A, B) restricted to the named states (and inputs, default all)."""
        i = [self.states.index(s) for s in states]
        j = [self.inputs.index(u) for u in (inputs or self.inputs)]
        return self.A[np.ix_(i, i)], self.B[np.ix_(i, j)]

    def ss(self, states, inputs, outputs):
        """python-control state space of a subsystem with the named outputs (states)."""
        import control as ct

        a, b = self.sub(states, inputs)
        c = np.zeros((len(outputs), len(states)))
        for k, y in enumerate(outputs):
            c[k, states.index(y)] = 1.0
        return ct.ss(a, b, c, np.zeros((len(outputs), len(inputs))))


def _apply_inputs(names, values) -> dict[str, float]:
    props: dict[str, float] = {}
    for n, v in zip(names, values, strict=False):
        if n == "throttle":
            props.update(dict.fromkeys(_THROTTLE_PROPS, v))
        else:
            props[n] = v
    return props


def linearize(
    ev: JSBSimEvaluator, inputs=HAPS_INPUTS, x0: np.ndarray | None = None, u0: np.ndarray | None = None
) -> LinearModel:
    """A, B of the plant behind ``ev`` about its current state (or ``x0``) and current inputs
    (or ``u0``). The plant is left at (x0, u0)."""
    f = ev.fdm
    x0 = ev.read_state() if x0 is None else np.asarray(x0, float)
    if u0 is None:
        u0 = np.array([f[_THROTTLE_PROPS[0]] if n == "throttle" else f[n] for n in inputs])
    u0 = np.asarray(u0, float)
    n, m = len(x0), len(u0)
    A, B = np.zeros((n, n)), np.zeros((n, m))
    base = _apply_inputs(inputs, u0)
    for k in range(n):
        dx = np.zeros(n)
        dx[k] = STATE_STEPS[k]
        fp = ev.derivatives(x0 + dx, base)
        fm = ev.derivatives(x0 - dx, base)
        A[:, k] = (fp - fm) / (2 * STATE_STEPS[k])
    for k in range(m):
        h = 1e-3
        up, um = u0.copy(), u0.copy()
        up[k] += h
        um[k] -= h
        fp = ev.derivatives(x0, _apply_inputs(inputs, up))
        fm = ev.derivatives(x0, _apply_inputs(inputs, um))
        B[:, k] = (fp - fm) / (2 * h)
    ev.derivatives(x0, base)
    return LinearModel(A, B, x0, u0, inputs=tuple(inputs))
