"""The thesis's Monte-Carlo study of the MPTP heuristics (seed 002, 6.2) on synthetic storm fields.

    python benchmarks/bench_mptp_montecarlo.py run [--trials 10000] [--per-field 10] [--workers 2]
        [--seed 1] [--dask ADDRESS] [--out benchmarks/results/mptp_mc]
    python benchmarks/bench_mptp_montecarlo.py table [--out benchmarks/results/mptp_mc] [--write]

``run`` plans every trial once per heuristic (sim/testbeds/mptp_montecarlo.py) on a process pool
(or a Dask cluster's executor), storing each field's rows in ``--out``/fields as it finishes (an
interrupted run resumes, from any checkout whose study configuration is the same), then
writes ``trials.csv`` (one row per trial and heuristic) and ``summary.json`` and prints the
Markdown table; ``table`` does the last two from the stored fields; ``--write``
puts the table into docs/mptp.md (between its ``montecarlo`` markers). Success counts
are deterministic for a seed; runtimes are the worker's CPU time per search on this (shared)
machine, so the table also gives them as ratios to EDH measured on the same trials in the same run.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sim.testbeds import mptp_mc_stats as stats  # noqa: E402
from sim.testbeds.mptp_montecarlo import run_study  # noqa: E402
from sim.testbeds.mptp_tables import DOC, replace_generated  # noqa: E402

OUT = ROOT / "benchmarks" / "results" / "mptp_mc"


def _stored_rows(out: Path) -> list[dict]:
    return [r for p in sorted((out / "fields").glob("field_*.json")) for r in json.loads(p.read_text())["rows"]]


def write_results(rows: list[dict], out: Path) -> dict:
    """trials.csv and summary.json in ``out``; returns the summary."""
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "trials.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    summary = stats.summarise(rows)
    (out / "summary.json").write_text(json.dumps(summary, indent=1, sort_keys=True))
    return summary


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("command", choices=("run", "table"))
    ap.add_argument("--trials", type=int, default=10_000)
    ap.add_argument("--per-field", type=int, default=10, help="trials per storm field")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1, help="master seed of the trial draws")
    ap.add_argument("--dask", metavar="ADDRESS", help="run on this Dask scheduler instead of a process pool")
    ap.add_argument(
        "--out",
        type=Path,
        default=OUT,
        help="directory of the resume data (fields/) and the results; for a long run put it outside the "
        "checkout, e.g. /work/mptp_mc, so that it survives the worktree's removal",
    )
    ap.add_argument("--write", action="store_true", help=f"put the table into {DOC}")
    a = ap.parse_args(argv)
    if a.trials < 1 or a.per_field < 1 or a.workers < 1:
        ap.error("--trials, --per-field and --workers must be >= 1")
    if a.command == "run":
        executor, client = None, None
        if a.dask:
            from distributed import Client

            client = Client(a.dask)
            executor = client.get_executor()
        wall = time.perf_counter()
        done = [0]

        def progress(k: int, n: int, field: int, rows: list[dict]) -> None:
            done[0] += len(rows)
            ok = {
                h: sum(r["success"] for r in rows if r["heuristic"] == h)
                for h in dict.fromkeys(r["heuristic"] for r in rows)
            }
            el = time.perf_counter() - wall
            eta = el / k * (n - k)
            succ = ", ".join(f"{h} {s}" for h, s in ok.items())
            print(
                f"[{k}/{n} fields] field {field}: {succ} of {len(rows) // len(ok)}; {el:.0f} s, eta {eta:.0f} s",
                flush=True,
            )

        try:
            rows = run_study(a.trials, a.per_field, a.seed, a.out, executor, a.workers, progress)
        finally:
            if client is not None:
                client.close()
    else:
        rows = _stored_rows(a.out)
        if not rows:
            ap.error(f"no stored fields in {a.out / 'fields'}")
    summary = write_results(rows, a.out)
    table = stats.markdown(summary)
    print(table)
    if a.write:
        DOC.write_text(replace_generated(DOC.read_text(), "montecarlo", table))


if __name__ == "__main__":
    main()
