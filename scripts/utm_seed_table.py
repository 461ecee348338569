"""The S10-S13 authority-against-virtual-UTM table of docs/rules.md from the slow test's JUnit XML.

    python -m pytest -q -n 2 -m slow tests/test_utm_scenarios.py -k 20_seeds -o junit_family=legacy --junitxml=X.xml
    python scripts/utm_seed_table.py X.xml

One row per scenario: its case margin [m], the seeds flown, the tests passed, how many runs of
each kind keep the margin, each kind's smallest closest separation (its seed) and median [m],
and per seed virtual -> authority [m] (✗: below the margin). The margins are the test's.
"""

from __future__ import annotations

import argparse
import re
import statistics
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_utm_scenarios import EXPECTED

CASE = re.compile(r"\[(?P<name>[^-\]]+)-(?P<seed>\d+)\]$")


def rows(xml: str) -> dict[str, dict[int, dict]]:
    """Per scenario and seed: ``passed`` and the recorded properties (floats where numeric)."""
    out: dict[str, dict[int, dict]] = {}
    for case in ET.parse(xml).getroot().iter("testcase"):
        m = CASE.search(case.get("name", ""))
        if not m or "20_seeds" not in case.get("name", ""):
            continue
        props: dict = {p.get("name"): p.get("value") for p in case.iter("property")}
        for k in ("virtual_m", "authority_m"):
            props[k] = float(props[k]) if props.get(k) not in (None, "") else None
        props["passed"] = case.find("failure") is None and case.find("error") is None
        out.setdefault(m["name"], {})[int(m["seed"])] = props
    return out


def _summary(seeds: dict[int, dict], key: str, margin: float) -> tuple[int, str]:
    """Runs of kind ``key`` keeping ``margin``, and "min (seed) / median" [m]."""
    vals = {s: seeds[s][key] for s in sorted(seeds) if seeds[s][key] is not None}
    if not vals:
        return 0, "-"
    low = min(vals, key=vals.__getitem__)
    kept = sum(v >= margin for v in vals.values())
    return kept, f"{vals[low]:.1f} ({low}) / {statistics.median(vals.values()):.1f}"


def _mark(v: float | None, margin: float) -> str:
    return "-" if v is None else f"{v:.1f}" + ("✗" if v < margin else "")


def table(results: dict[str, dict[int, dict]]) -> str:
    head = (
        "| scenario | margin [m] | seeds flown | test passed | authority ≥ margin | virtual ≥ margin "
        "| authority min (seed) / median [m] | virtual min (seed) / median [m] | per seed: virtual → authority [m] |"
    )
    lines = [head, "|" + "---|" * 9]
    for name in sorted(results):
        margin, seeds = EXPECTED[name][2], results[name]
        order = sorted(seeds)
        a_kept, a_txt = _summary(seeds, "authority_m", margin)
        v_kept, v_txt = _summary(seeds, "virtual_m", margin)
        per = ", ".join(
            f"{s}: {_mark(seeds[s]['virtual_m'], margin)} → {_mark(seeds[s]['authority_m'], margin)}" for s in order
        )
        passed = sum(seeds[s]["passed"] for s in order)
        cells = [name, f"{margin:g}", f"{len(order)} ({order[0]}-{order[-1]})", f"{passed} of {len(order)}"]
        cells += [str(a_kept), str(v_kept), a_txt, v_txt, per]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("xml")
    print(table(rows(ap.parse_args().xml)))


if __name__ == "__main__":
    main()
