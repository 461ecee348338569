"""Before/after figures of an encounter campaign flown twice (docs/encounters.md): the draws
both ``results.csv`` files hold, mitigated rows compared per draw, unmitigated rows checked for
equality (they do not run the avoider).

    python scripts/compare_encounter_rows.py BEFORE/results.csv AFTER/results.csv [--worse 0.5]

Prints, over the shared draws: mitigated NMACs and completed missions before/after; median and
smallest minimum horizontal separation and closest 3-D distance [m]; mean mission time of the
completed runs [s]; how many unmitigated rows are unchanged; the draws whose closest 3-D
distance shrank by more than ``--worse`` [m].
"""

from __future__ import annotations

import argparse

import numpy as np
import pandas as pd

COLUMNS = {
    "param.encounter": "draw",
    "param.mode": "mode",
    "metric.separation.own-intruder.min_horizontal_m": "horizontal",
    "metric.separation.own-intruder.vertical_at_min_horizontal_m": "vertical",
    "metric.separation.own-intruder.distance_m": "closest",
    "metric.separation.own-intruder.nmac": "nmac",
    "metric.vehicles.own.mission.complete": "complete",
    "metric.vehicles.own.mission.time_s": "time",
}


def rows(path: str) -> pd.DataFrame:
    """The compared columns of a campaign's ``results.csv``, one row per run."""
    return pd.read_csv(path)[["run_id", *COLUMNS]].rename(columns=COLUMNS)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before")
    ap.add_argument("after")
    ap.add_argument("--worse", type=float, default=0.5, help="closest-distance loss to list [m]")
    args = ap.parse_args()
    both = rows(args.before).merge(rows(args.after), on=["run_id", "draw", "mode"], suffixes=("_b", "_a"))
    unm = both[both["mode"] == "unmitigated"]
    same = np.isclose(unm["horizontal_b"], unm["horizontal_a"]) & np.isclose(unm["closest_b"], unm["closest_a"])
    mit = both[both["mode"] == "mitigated"]
    print(f"draws {len(mit)}: unmitigated rows unchanged {int(same.sum())} of {len(unm)}")
    for key in ("nmac", "complete"):
        print(f"mitigated {key}: {int(mit[key + '_b'].sum())} -> {int(mit[key + '_a'].sum())}")
    for key in ("horizontal", "closest"):
        b, a = mit[key + "_b"], mit[key + "_a"]
        print(f"{key} [m] median {b.median():.2f} -> {a.median():.2f}, smallest {b.min():.2f} -> {a.min():.2f}")
    t_b, t_a = mit["time_b"][mit["complete_b"]], mit["time_a"][mit["complete_a"]]
    print(f"mission time [s] mean {t_b.mean():.2f} -> {t_a.mean():.2f}")
    worse = mit[mit["closest_a"] < mit["closest_b"] - args.worse]
    print(f"closest distance smaller by more than {args.worse} m: {len(worse)}")
    cols = ["draw", "horizontal_b", "vertical_b", "closest_b", "horizontal_a", "vertical_a", "closest_a"]
    if len(worse):
        print(worse[cols].round(2).to_string(index=False))


if __name__ == "__main__":
    main()
