"""Peak memory of ``cosim replay`` and ``cosim export`` against the log's length.

Flies the shipped ``scenarios/haps_box_mission.toml`` for each ``--durations`` (default 150 s
and 1200 s; 10 Hz log), then runs ``replay`` and ``export --format parquet`` (and ``csv``) on each
log in a fresh interpreter and reports that interpreter's peak resident set size
(``ru_maxrss`` of the command's own process) and its growth from the shortest log to the
longest. ``--baseline DIR`` runs the same commands with the code of another checkout first on
``sys.path`` (e.g. a worktree of the commit before streaming), in the same run, on the same
logs, so the comparison does not depend on the machine's load.

    python benchmarks/bench_replay_memory.py [--durations 150 1200] [--baseline DIR] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "haps_box_mission.toml"
COMMANDS = {
    "replay": ["replay", "{log}", "-o", "{out}"],
    "export_parquet": ["export", "{log}", "--format", "parquet", "-o", "{out}", "-q"],
    "export_csv": ["export", "{log}", "--format", "csv", "-o", "{out}", "-q"],
}


def fly(duration_s: float, out: Path) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "sim.cli", "run", str(SCENARIO), "-o", str(out), "--duration", str(duration_s), "-q"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=False,
    )
    if proc.returncode != 0:
        raise RuntimeError(f"run failed: {proc.stderr.strip()[-300:]}")


def peak_rss_mib(code_root: Path, args: list[str]) -> float:
    """Run ``cosim ARGS`` with ``code_root`` first on sys.path; its own peak RSS [MiB]."""
    code = (
        f"import sys, resource; sys.path.insert(0, {str(code_root)!r})\n"
        "from sim.cli import main\n"
        f"rc = main({args!r})\n"
        "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)\n"
        "sys.exit(rc)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], cwd=code_root, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"{code_root}: cosim {' '.join(args)} failed: {proc.stderr.strip()[-300:]}")
    return int(proc.stdout.split()[-1]) / 1024.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--durations", type=float, nargs="+", default=[150.0, 1200.0], help="sim seconds per log")
    ap.add_argument("--baseline", type=Path, help="another checkout to measure on the same logs")
    ap.add_argument("--json", type=Path, help="write the results here")
    args = ap.parse_args()
    codes = {"this": ROOT, **({"baseline": args.baseline.resolve()} if args.baseline else {})}
    results: dict = {"scenario": SCENARIO.name, "logs": {}, "peak_rss_mib": {}}
    with tempfile.TemporaryDirectory() as tmp:
        logs = {}
        for d in args.durations:
            log = Path(tmp) / f"box_{d:g}s.mcap"
            fly(d, log)
            logs[d] = log
            results["logs"][f"{d:g}"] = {"mib": log.stat().st_size / 2**20}
        for code_name, code_root in codes.items():
            for cmd, template in COMMANDS.items():
                peaks = {}
                for d, log in logs.items():
                    out = Path(tmp) / f"{code_name}_{cmd}_{d:g}"
                    argv = [a.format(log=log, out=out) for a in template]
                    peaks[f"{d:g}"] = peak_rss_mib(code_root, argv)
                first, last = peaks[f"{min(logs):g}"], peaks[f"{max(logs):g}"]
                results["peak_rss_mib"].setdefault(code_name, {})[cmd] = {**peaks, "growth_mib": last - first}
                print(f"{code_name:8s} {cmd:15s} " + "  ".join(f"{k} s: {v:6.1f} MiB" for k, v in peaks.items()))
    print(json.dumps(results, indent=2))
    if args.json:
        args.json.write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":
    main()
