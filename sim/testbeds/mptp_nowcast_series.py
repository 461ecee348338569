"""Writes the nowcast-file series of scenarios/mptp/nowcast_crossing.toml: a seeded synthetic
storm field like storm_crossing.toml's (three slow cells on a 50 km leg), one WGS84 nowcast
GeoJSON file per issue every 5 min (docs/mptp.md format; steps of 10 min over 1 h),
coordinates rounded to 1e-6 deg (~0.1 m).

    python -m sim.testbeds.mptp_nowcast_series [FOLDER]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from sim.geodesy import GeoPoint
from sim.nowcast_files import dump_nowcast
from sim.storm_synthetic import StormField

ORIGIN = GeoPoint(47.0, 8.0, 0.0)
FOLDER = Path(__file__).resolve().parents[2] / "scenarios" / "mptp" / "nowcasts"
ISSUE_PERIOD_S, HORIZON_S, STEP_S, LAST_ISSUE_S = 300.0, 3600.0, 600.0, 2700.0


def field() -> StormField:
    return StormField(
        seed=5,
        n_cells=3,
        size_m=(60_000.0, 60_000.0),
        mean_velocity=(0.0, 2.0),
        speed_spread=0.5,
        mean_radius_m=3000.0,
        split_prob=0.0,
        life_s=5 * 3600.0,
        centres=np.array([[0.0, 22_000.0], [9000.0, 30_000.0], [-9000.0, 32_000.0]]),
        births_after_t0=False,
    )


def _rounded(x):
    if isinstance(x, float):
        return round(x, 6)
    if isinstance(x, list):
        return [_rounded(v) for v in x]
    if isinstance(x, dict):
        return {k: _rounded(v) for k, v in x.items()}
    return x


def write_series(folder: Path = FOLDER) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    f, paths = field(), []
    for t in np.arange(0.0, LAST_ISSUE_S + 1.0, ISSUE_PERIOD_S):
        doc = _rounded(dump_nowcast(f.nowcast(float(t), HORIZON_S, STEP_S), "wgs84", ORIGIN))
        path = folder / f"nowcast_{int(t):05d}s.geojson"
        path.write_text(json.dumps(doc, separators=(",", ":")))
        paths.append(path)
    return paths


if __name__ == "__main__":
    for p in write_series(Path(sys.argv[1]) if len(sys.argv) > 1 else FOLDER):
        print(p)
