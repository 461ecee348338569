"""The MPTP's arrival prediction in closed loop in wind, over seeds, for each wind source.

Flies ``scenarios/mptp/wind_crossing.toml`` (JSBSim HAPS on its EKF, steady 15 m/s wind) once
per seed and ``wind_forecast`` source with the helper of the slow closed-loop wind tests
(``tests/test_mptp_wind.py::_closed_loop_arrival_errors``: it asserts that the flight arrives and
never enters a true cell) and prints the relative errors of two complete plans' predicted
arrivals against the flown one: the first plan's and the plan flown to the goal's.

    python scripts/mptp_wind_seeds.py --sources scenario,estimate,none --seeds 1-20 --workers 2

``--wind standard_profile`` flies the standard altitude profile alone instead of the file's steady
wind (the tests' ``CLOSED_LOOP_WINDS``).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from multiprocessing import Pool
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

import test_mptp_wind  # noqa: E402


def one(job: tuple[str, int, str]) -> tuple[str, int, tuple[float, float] | str]:
    source, seed, wind = job
    with tempfile.TemporaryDirectory() as d:
        try:
            table = test_mptp_wind.CLOSED_LOOP_WINDS[wind]
            return source, seed, test_mptp_wind._closed_loop_arrival_errors(Path(d), source, table, seed)
        except AssertionError as exc:
            return source, seed, f"failed: {exc}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sources", default="scenario,estimate,none", help="wind_forecast values, comma-separated")
    ap.add_argument("--seeds", default="1-20", help="first-last")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--wind", default="steady_15", choices=sorted(test_mptp_wind.CLOSED_LOOP_WINDS))
    a = ap.parse_args()
    lo, hi = (int(x) for x in a.seeds.split("-"))
    jobs = [(s, seed, a.wind) for seed in range(lo, hi + 1) for s in a.sources.split(",")]
    errors: dict[str, list[tuple[float, float]]] = {}
    with Pool(a.workers) as pool:
        for source, seed, err in pool.imap(one, jobs):
            text = err if isinstance(err, str) else f"first plan {100 * err[0]:.2f} %, flown plan {100 * err[1]:.2f} %"
            print(f"{source} seed {seed}: {text}", flush=True)
            if not isinstance(err, str):
                errors.setdefault(source, []).append(err)
    for source, pairs in errors.items():
        for k, which in enumerate(("first plan", "flown plan")):
            v = [p[k] for p in pairs]
            print(
                f"{source}, {which}: {len(v)} flights, median {100 * statistics.median(v):.2f} %, "
                f"max {100 * max(v):.2f} %, within 3 % on {sum(e < 0.03 for e in v)}"
            )


if __name__ == "__main__":
    main()
