"""What JSBSim's Milspec (MIL-F-8785C Dryden) turbulence gives at altitude, per scenario level.

    PYTHONPATH=. python scripts/turbulence_at_altitude.py [--seconds 300]

For each altitude and ``[wind] turbulence`` level: a trimmed HAPS (the JSBSim model alone, no
controller) flies ``--seconds`` of sim time; prints the standard deviation of the turbulence
velocity (``atmosphere/total-wind-*`` with no steady wind), NED [m/s], sampled at 10 Hz, and its
largest magnitude. Above 2000 ft JSBSim takes the intensity from MIL-F-8785C's
probability-of-exceedance table, which is zero at high altitude for the rarer levels.
"""

from __future__ import annotations

import argparse

import numpy as np

from aircraft.registry import get_airframe
from sim import scenario as sc
from sim.core.constants import FT
from sim.environment import TURBULENCE, apply_turbulence
from sim.geodesy import GeoPoint
from sim.jsbsim_plant import InitialConditions, JSBSimPlant

ALTITUDES_M = (18000.0, 20000.0, 21000.0)


def turbulence_samples(alt_m: float, level: str, seconds: float, seed: int = 7) -> np.ndarray:
    """Turbulence velocity NED [m/s] at 10 Hz felt by the trimmed HAPS at ``alt_m`` [m MSL]."""
    af = get_airframe("haps")
    origin = GeoPoint(47.0, 8.0, alt_m)
    plant = JSBSimPlant(af.jsbsim_model, 1.0 / af.plant_hz, origin, af.folder)
    plant.initialise(InitialConditions(position=origin, tas_mps=30.0))
    plant.trim()
    apply_turbulence(plant, sc.Wind(turbulence=level), seed)
    every = af.plant_hz // 10
    out = []
    for _ in range(int(seconds * 10)):
        plant.step(every)
        out.append([plant[f"atmosphere/total-wind-{a}-fps"] * FT for a in ("north", "east", "down")])
    return np.array(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=300.0)
    args = ap.parse_args()
    print("| altitude [km] | level | std north / east / down [m/s] | max [m/s] |")
    print("|---|---|---|---|")
    for alt in ALTITUDES_M:
        for level in (k for k in TURBULENCE if k != "none"):
            w = turbulence_samples(alt, level, args.seconds)
            std = " / ".join(f"{s:.2f}" for s in w.std(axis=0))
            print(f"| {alt / 1000:g} | {level} | {std} | {np.linalg.norm(w, axis=1).max():.2f} |")


if __name__ == "__main__":
    main()
