"""scripts/compare_log_payloads.py, the refactoring check of issue 14: a changed payload byte is a
difference; a channel's declared wall-clock fields and a wall-clock-only channel are not."""

from __future__ import annotations

import importlib.util
from pathlib import Path

from sim.mcap_log import McapLog

_spec = importlib.util.spec_from_file_location(
    "compare_log_payloads", Path(__file__).resolve().parents[1] / "scripts" / "compare_log_payloads.py"
)
assert _spec is not None and _spec.loader is not None
compare = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(compare)

SCHEMA = {"title": "test.Record", "type": "object"}
PLAN_META = {"wallclock": "true", "wallclock_fields": "diagnostics.runtime_s"}


def _log(path: Path, heading: float, runtime: float, latency: float) -> Path:
    with McapLog(path, 0, background=False) as log:
        for k in range(3):
            t = float(k)
            log.write_json(
                "/v/plan", t, {"t": t, "heading": heading, "diagnostics": {"runtime_s": runtime}}, SCHEMA, PLAN_META
            )
            log.write_json("/v/plan/latency", t, {"seconds": latency}, SCHEMA, {"wallclock": "true"})
    return path


def test_only_declared_wall_clock_fields_may_differ(tmp_path, capsys):
    a = _log(tmp_path / "a.mcap", heading=1.0, runtime=0.1, latency=0.01)
    same_but_timing = _log(tmp_path / "b.mcap", heading=1.0, runtime=0.7, latency=0.09)
    other_heading = _log(tmp_path / "c.mcap", heading=1.0 + 1e-12, runtime=0.1, latency=0.01)
    assert compare.main([str(a), str(same_but_timing)]) == 0
    assert compare.main([str(a), str(other_heading)]) == 1
    out = capsys.readouterr().out
    latency = next(line for line in out.splitlines() if line.startswith("/v/plan/latency"))
    plan = next(line for line in out.splitlines() if line.split()[0] == "/v/plan")
    assert "not judged" in latency and "not judged" not in plan
