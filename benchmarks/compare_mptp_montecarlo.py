"""MPTP Monte-Carlo trials (sim/testbeds/mptp_montecarlo.py): this code against a baseline checkout.

    git worktree add --detach /tmp/mptp-base main
    python benchmarks/compare_mptp_montecarlo.py --baseline /tmp/mptp-base [--fields 0-3]
        [--per-field 10] [--seed 1]
    python benchmarks/compare_mptp_montecarlo.py --stored /work/runs/mptp_mc [--fields 0-3]

Runs the study's fields (``run_field``: one storm field, its trials, every heuristic) with this
checkout's code and with the baseline's, each in its own process (the code is imported from
that checkout), field by field alternating between the two so that load changes hit both
alike. Prints the CPU time per trial of each code (the process CPU time of the whole field:
field, timeline, trial draws and searches, divided by its trials), their ratio, whether both
codes have the same study fingerprint (the key of stored fields) and whether every row is the
same in the fields that decide the study (success, status, EXST, TRST, length, arrival, the
trial's draw); the rows that differ are listed. With ``--stored DIR`` (a study's ``--out``) the
rows are compared with the fields stored there instead (whether a run may be resumed with this
code; no CPU ratio: those rows come from another run). Writes
benchmarks/results/mptp_mc_compare.json.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TIMES = ("runtime_s", "wall_s")  # the only row fields allowed to differ


def worker(root: Path, field: int, per_field: int, seed: int) -> dict:
    """Rows of one field with the code of checkout ``root`` and the process CPU time [s]."""
    import time

    sys.path.insert(0, str(root))
    from sim.testbeds import mptp_montecarlo

    cpu = time.process_time()
    rows = mptp_montecarlo.run_field(field, per_field, seed)
    return {
        "rows": rows,
        "cpu_s": time.process_time() - cpu,
        "fingerprint": mptp_montecarlo.study_fingerprint(),
    }


def run_worker(root: Path, field: int, per_field: int, seed: int) -> dict:
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", str(field), "--root", str(root)]
    cmd += ["--per-field", str(per_field), "--seed", str(seed)]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True, cwd=root).stdout
    return json.loads(out.splitlines()[-1])


def same(a: object, b: object) -> bool:
    """Equal values, NaN equal to NaN (the length and arrival of failed trials)."""
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return a == b


def row_differences(a: list[dict], b: list[dict]) -> list[str]:
    """Descriptions of the rows of ``a`` and ``b`` (same order) that differ outside TIMES."""
    out = [f"row count {len(a)} != {len(b)}"] if len(a) != len(b) else []
    for ra, rb in zip(a, b, strict=False):
        keys = (set(ra) | set(rb)) - set(TIMES)
        bad = sorted(k for k in keys if not same(ra.get(k), rb.get(k)))
        if bad:
            out.append(f"field {ra['field']} trial {ra['index']} {ra['heuristic']}: " + ", ".join(bad))
    return out


def stored_field(out: Path, field: int, per_field: int, seed: int) -> dict:
    """A field stored by a study run in ``out`` as a baseline run (no CPU time)."""
    d = json.loads((out / "fields" / f"field_{field:05d}.json").read_text())
    if (d["seed"], d["n_trials"]) != (seed, per_field):
        raise SystemExit(f"stored field {field}: seed {d['seed']}, {d['n_trials']} trials, not {seed}, {per_field}")
    return {"rows": d["rows"], "cpu_s": float("nan"), "fingerprint": d["study"]}


def parse_fields(text: str) -> list[int]:
    """'0-3' or '0,5,9' -> field indices."""
    if "-" in text:
        lo, hi = (int(x) for x in text.split("-"))
        return list(range(lo, hi + 1))
    return [int(x) for x in text.split(",")]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--baseline", type=Path, help="checkout of the code to compare with (e.g. a git worktree)")
    ap.add_argument("--stored", type=Path, help="compare with the fields stored in this study --out instead")
    ap.add_argument("--fields", default="0-3", help="field indices, 'a-b' or 'a,b,c'")
    ap.add_argument("--per-field", type=int, default=10, help="trials per field (the study's: 10)")
    ap.add_argument("--seed", type=int, default=1, help="master seed of the trial draws (the study's: 1)")
    ap.add_argument("--worker", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--root", type=Path, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.worker is not None:
        print(json.dumps(worker(a.root, a.worker, a.per_field, a.seed)))
        return
    if a.stored is None and (
        a.baseline is None or not (a.baseline / "sim" / "testbeds" / "mptp_montecarlo.py").is_file()
    ):
        ap.error("give --stored, or --baseline as a checkout of this repository (with sim/testbeds/mptp_montecarlo.py)")
    codes = {"new": ROOT, "baseline": a.baseline.resolve() if a.stored is None else a.stored.resolve()}
    runs: dict[str, list[dict]] = {k: [] for k in codes}
    fields = parse_fields(a.fields)
    for f in fields:
        runs["new"].append(run_worker(ROOT, f, a.per_field, a.seed))
        if a.stored is None:
            runs["baseline"].append(run_worker(codes["baseline"], f, a.per_field, a.seed))
        else:
            runs["baseline"].append(stored_field(codes["baseline"], f, a.per_field, a.seed))
    trials = len({(r["field"], r["index"]) for run in runs["new"] for r in run["rows"]})
    cpu = {k: sum(r["cpu_s"] for r in runs[k]) / max(trials, 1) for k in codes}
    diffs = [
        d for rn, rb in zip(runs["new"], runs["baseline"], strict=True) for d in row_differences(rn["rows"], rb["rows"])
    ]
    prints = {k: runs[k][0]["fingerprint"] for k in codes}
    result = {
        "fields": fields,
        "per_field": a.per_field,
        "seed": a.seed,
        "trials": trials,
        "rows": sum(len(r["rows"]) for r in runs["new"]),
        "cpu_per_trial_s": cpu,
        "ratio": cpu["baseline"] / cpu["new"],
        "fingerprints": prints,
        "rows_differing": diffs,
    }
    out = ROOT / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    (out / "mptp_mc_compare.json").write_text(json.dumps(result, indent=1))
    print(f"fields {a.fields}: {trials} trials, {result['rows']} rows; baseline {codes['baseline']}")
    print(f"CPU per trial baseline / new: {cpu['baseline']:.3f} / {cpu['new']:.3f} s, ratio {result['ratio']:.2f}")
    print(f"study fingerprint baseline / new: {prints['baseline']} / {prints['new']}")
    print(f"rows differing (outside {', '.join(TIMES)}): {len(diffs)}")
    for d in diffs:
        print("  " + d)


if __name__ == "__main__":
    main()
