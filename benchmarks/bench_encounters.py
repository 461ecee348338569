"""Encounter campaign throughput: encounters per core-hour per shipped campaign, and the
process-pool speed-up on 2 workers.

For each campaign in ``scenarios/encounters/`` (or ``--campaign``), the first ``--encounters``
draws are flown (both modes) by ``sim.encounters.campaign.run_campaign`` into a fresh temporary
folder, once on 1 worker and, for ``--speedup`` campaigns, once on 2. CPU time is this process's
and its reaped children's (pool workers, MCAP writers) user + system time. Reported per campaign:
CPU seconds per encounter, encounters per core-hour, wall time per worker count, the speed-up
(wall 1 worker / wall 2 workers) and whether both gave the same summary. JSON:
benchmarks/results/encounters.json. Timings on a shared machine vary with its load.

    python benchmarks/bench_encounters.py [--encounters 4] [--campaign NAME ...] [--speedup NAME ...]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sim.encounters.campaign import load_campaign, run_campaign  # noqa: E402

CAMPAIGNS = ROOT / "scenarios" / "encounters"


def cpu_seconds() -> float:
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def fly(path: Path, n: int, workers: int) -> tuple[float, float, dict, int]:
    """(wall [s], CPU [s], summary, encounters flown) of the first ``n`` draws on ``workers``."""
    with tempfile.TemporaryDirectory() as tmp:
        c = load_campaign(path, tmp, limit=n)
        c0, w0 = cpu_seconds(), time.perf_counter()
        summary = run_campaign(c, tmp, workers=workers, resume=False)
        return time.perf_counter() - w0, cpu_seconds() - c0, summary, len(c.encounters)


def strip(summary: dict) -> str:
    return json.dumps(summary, sort_keys=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--encounters", type=int, default=4)
    ap.add_argument("--campaign", nargs="*", help="campaign file stems (default: all shipped)")
    ap.add_argument("--speedup", nargs="*", default=["geometric_quad_pairs"], help="campaigns also flown on 2 workers")
    args = ap.parse_args(argv)
    names = args.campaign or sorted(p.stem for p in CAMPAIGNS.glob("*.toml"))
    result: dict = {
        "encounters_per_campaign": args.encounters,
        "cpu_count": os.cpu_count(),
        "machine": platform.processor() or platform.machine(),
        "python": platform.python_version(),
        "campaigns": {},
    }
    for name in names:
        path = CAMPAIGNS / f"{name}.toml"
        wall1, cpu, summary1, n = fly(path, args.encounters, 1)
        row = {
            "encounters": n,
            "cpu_s_per_encounter": round(cpu / n, 2),
            "encounters_per_core_hour": round(3600 * n / cpu, 1),
            "wall_1_worker_s": round(wall1, 2),
        }
        if name in args.speedup:
            wall2, _, summary2, _ = fly(path, args.encounters, 2)
            row |= {
                "wall_2_workers_s": round(wall2, 2),
                "speedup_2_vs_1": round(wall1 / wall2, 3),
                "identical_summary": strip(summary1) == strip(summary2),
            }
        result["campaigns"][name] = row
        print(name, row, flush=True)
    out = ROOT / "benchmarks" / "results" / "encounters.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
