"""Cost of crash detection (sim/contacts.py) against the plant stepping it rides on, same run.

- ``check``: one ``World.check_contacts`` (obstacles, vehicles, objects, the ground watches'
  reports) on a shipped scenario, against the bare JSBSim steps of all its vehicles between two
  checks (the plant work one check interval costs).
- ``watch``: a quadrotor stepped 1 s with its ground watch attached, far from the ground (one
  property read per step) and resting on the ground (the hull placed every step), against the same plant
  stepped without it.

    python benchmarks/bench_contacts.py [--repeat 5]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from aircraft.registry import get_airframe  # noqa: E402
from sim.contacts import GroundWatch  # noqa: E402
from sim.geodesy import GeoPoint  # noqa: E402
from sim.hull import load_hull  # noqa: E402
from sim.jsbsim_plant import InitialConditions, JSBSimPlant  # noqa: E402
from sim.mcap_log import McapLog  # noqa: E402
from sim.scenario import parse_scenario  # noqa: E402
from sim.world import World  # noqa: E402

SCENARIOS = ("reachset/building", "reachset_fleet8", "rules/mixed_haps_swarm")


def _median_s(fn, n: int, repeat: int) -> float:
    """Median over ``repeat`` of the wall time of ``n`` calls of ``fn``, per call [s]."""
    out = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        out.append((time.perf_counter() - t0) / n)
    return statistics.median(out)


def bench_check(name: str, repeat: int) -> dict:
    data = tomllib.loads((ROOT / "scenarios" / f"{name}.toml").read_text())
    with tempfile.TemporaryDirectory() as tmp:
        log = McapLog(Path(tmp) / "b.mcap", 0)
        try:
            world = World(parse_scenario(data, name), log)
            hz = world.contact_hz
            check = _median_s(lambda: world.check_contacts(1.0), 200, repeat)
            plants = [(v.plant, v.airframe.plant_hz // hz) for v in world.vehicles]
            for p, _ in plants:
                p.after_step = None  # bare stepping

            def step_all() -> None:
                for p, k in plants:
                    p.step(k)

            step = _median_s(step_all, 50, repeat)
        finally:
            log.close()
    return {"scenario": name, "vehicles": len(plants), "check_us": check * 1e6, "plants_us": step * 1e6}


def bench_watch(repeat: int) -> list[dict]:
    """Two identical plants, one watched; a falling plant (no controller) starts 5 km up so that
    it stays far from the ground for the whole measurement."""
    quad = get_airframe("quadrotor")
    ground = GeoPoint(47.0, 8.0, 400.0)
    hull = load_hull(quad.jsbsim_file)
    rows = []
    for label, alt, on_ground in (("far from the ground", 5400.0, False), ("on the ground", 400.0, True)):
        plants = []
        for _ in range(2):
            plant = JSBSimPlant(quad.jsbsim_model, 1.0 / quad.plant_hz, ground, quad.folder)
            ic = InitialConditions(GeoPoint(47.0, 8.0, alt), on_ground=on_ground, terrain_alt_m=ground.alt_m)
            plant.initialise(ic)
            plants.append(plant)
        GroundWatch(hull, quad.crash_sink_mps).attach(plants[1])
        bare, watched = (_median_s(lambda p=p: p.step(quad.plant_hz), 3, repeat) for p in plants)
        rows.append({"case": label, "bare_ms": bare * 1e3, "watched_ms": watched * 1e3})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    print("| scenario | vehicles | one check [us] | their plant steps per check interval [us] | ratio |")
    print("|---|---|---|---|---|")
    for name in SCENARIOS:
        r = bench_check(name, args.repeat)
        ratio = r["check_us"] / r["plants_us"]
        print(f"| {name} | {r['vehicles']} | {r['check_us']:.0f} | {r['plants_us']:.0f} | {ratio:.2f} |")
    print()
    print("| quadrotor, 1 s at 240 Hz | bare [ms] | with the ground watch [ms] | ratio |")
    print("|---|---|---|---|")
    for r in bench_watch(args.repeat):
        print(f"| {r['case']} | {r['bare_ms']:.1f} | {r['watched_ms']:.1f} | {r['watched_ms'] / r['bare_ms']:.2f} |")


if __name__ == "__main__":
    main()
