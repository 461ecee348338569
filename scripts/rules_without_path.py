"""Which rule of the air leaves a rules planner without a path (docs/encounters.md finding 18).

    python scripts/rules_without_path.py LOG.mcap VEHICLE [--from T0] [--to T1]

Re-runs VEHICLE's rules planner open-loop on the logged estimates and threats
(:func:`sim.replay.rerun.rerun_planner`) once with the logged options and once per enabled rule
left out, and prints, per run, the decision times [s] in [T0, T1] whose events include
``no_path``. A rule whose removal empties that list is what closes every path there.
"""

from __future__ import annotations

import argparse

from aircraft.registry import get_airframe
from sim.core.mission import Mission
from sim.core.plan import Plan, Planner, Threats
from sim.core.state import VehicleState
from sim.mcap_read import read_attached_scenario
from sim.replay.rerun import rerun_planner
from sim.scenario import Scenario
from sim.vehicle_setup import scenario_planner


def no_path_times(log: str, scenario: Scenario, vehicle: str, rules: list[str], t0: float, t1: float) -> list[float]:
    """Times in [t0, t1] of the re-run's new decisions that found no path, with ``rules`` enabled
    (``scenario``: the one attached to the log)."""
    cfg = next(v for v in scenario.vehicle if v.name == vehicle)
    options = cfg.planner.options.model_copy(update={"rules": rules})
    cfg = cfg.model_copy(update={"planner": cfg.planner.model_copy(update={"options": options})})
    af = get_airframe(cfg.aircraft)
    gains = af.make_controller(cfg.gains).gains
    found: list[float] = []

    def factory(mission: Mission) -> Planner:
        planner = scenario_planner(cfg, mission, af, gains, scenario.wind, scenario.origin_point.alt_m)
        plan = planner.plan

        def recording(estimate: VehicleState, threats: Threats, t: float) -> Plan:
            out = plan(estimate, threats, t)
            if out.t == t and t0 <= t <= t1 and "no_path" in str(out.diagnostics.get("events", "")):
                found.append(t)
            return out

        planner.plan = recording  # type: ignore[method-assign]
        return planner

    rerun_planner(log, vehicle, factory)
    return found


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("log")
    ap.add_argument("vehicle")
    ap.add_argument("--from", dest="t0", type=float, default=0.0, help="first decision time [s]")
    ap.add_argument("--to", dest="t1", type=float, default=float("inf"), help="last decision time [s]")
    args = ap.parse_args()
    scenario = read_attached_scenario(args.log)
    if scenario is None:
        raise SystemExit(f"{args.log}: the scenario is not attached; cannot rebuild the planner")
    enabled = list(next(v for v in scenario.vehicle if v.name == args.vehicle).planner.options.rules)
    for dropped in [None, *enabled]:
        rules = [r for r in enabled if r != dropped]
        times = no_path_times(args.log, scenario, args.vehicle, rules, args.t0, args.t1)
        label = "all rules" if dropped is None else f"without {dropped}"
        print(f"{label:32s} no_path at {', '.join(f'{t:g}' for t in times) or '-'}")


if __name__ == "__main__":
    main()
