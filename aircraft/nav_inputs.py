"""What the airframes' JSBSim inner loops (``systems/*.xml``) close on: the contract between
their FCS and the engine, which writes the estimate's values into them.

``ATTITUDE_SOURCE`` selects, every FCS step, the attitude and body rates the inner loops read:
0 (the XML default, also during JSBSim's trim) JSBSim's true ``attitude/*`` and
``velocities/[pqr]-rad_sec`` (ideal sensors, ``estimator = "perfect"``); 1 the values written
to ``ESTIMATE_PROPERTIES`` (an :class:`sim.core.state.AttitudeSample`: roll, pitch, yaw [rad],
3-2-1 Euler body FRD to NED; p, q, r [rad/s] body FRD), held until the next write.
"""

from __future__ import annotations

from sim.core.state import AttitudeSample

ATTITUDE_SOURCE = "ap/att-source"
ESTIMATE_PROPERTIES = (
    "ap/est-phi-rad",
    "ap/est-theta-rad",
    "ap/est-psi-rad",
    "ap/est-p-rps",
    "ap/est-q-rps",
    "ap/est-r-rps",
)


def estimate_values(sample: AttitudeSample) -> tuple[float, ...]:
    """The values of ``ESTIMATE_PROPERTIES``, in their order."""
    return (*sample.euler, *sample.rates_body)
