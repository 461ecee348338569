"""The pairwise visibility tests of the MPTP (guidance/mptp/visibility.py) hold at most
MAX_PAIRS pairs at once: a free space with many obstacle corners costs time, not memory that
grows with the square of its corners (issue 20: a corridor_opens replan was killed at 22 GB),
and a reduced visibility graph over GRAPH_PAIR_BUDGET pairs is not built: the search runs on
EDH and the plan's diagnostics say so."""

import tracemalloc

import numpy as np
import pytest
import shapely
from shapely.geometry import box

from guidance.mptp import visibility
from guidance.mptp.config import MptpConfig
from guidance.mptp.planner import MptpPlanner
from guidance.mptp.visibility import boundary_of, first_hit, reduced_graph
from sim.core.mission import Mission
from sim.core.plan import Plan, Threats
from sim.core.threats import StormSnapshot
from sim.testbeds.mptp_openloop import vehicle_state


def _scattered(n: int) -> visibility.Boundary:
    """A 100 km box with an n x n grid of 200 m squares taken out: 4 n^2 convex corners."""
    holes = [box(x, y, x + 200.0, y + 200.0) for x in np.linspace(1e3, 9e4, n) for y in np.linspace(1e3, 9e4, n)]
    return boundary_of(box(0.0, 0.0, 1e5, 1e5).difference(shapely.union_all(holes)))


def _peak(fn) -> tuple[object, int]:
    tracemalloc.start()
    try:
        out = fn()
        return out, tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_blocks_give_the_graph_and_the_hits_of_one_pass(monkeypatch):
    b = _scattered(6)
    whole = reduced_graph(b)
    p, q = b.verts[:60], b.verts[::-1][:60]
    hits = first_hit(p, q, b)
    monkeypatch.setattr(visibility, "MAX_PAIRS", 500)  # blocks of ~3 vertex rows, ~3 candidates
    assert all(np.array_equal(x, y) for x, y in zip(reduced_graph(b), whole, strict=True))
    assert np.array_equal(first_hit(p, q, b), hits)
    assert len(whole[0]) > 100 and np.isfinite(hits).any()


@pytest.mark.parametrize("fn", ["graph", "hits"])
def test_the_peak_memory_stays_within_the_pair_budget(monkeypatch, fn):
    """400 convex corners: 160,000 vertex pairs (and ~100,000 candidate-edge pairs); with a
    budget of 20,000 pairs the peak of numpy memory stays under 8 MB, where one pass holds
    tens of MB (fails with the blocks removed)."""
    b = _scattered(10)
    monkeypatch.setattr(visibility, "MAX_PAIRS", 20_000)
    i = np.arange(len(b.verts))
    calls = {
        "graph": lambda: reduced_graph(b),
        "hits": lambda: first_hit(b.verts[i % 40], b.verts[(i * 7) % len(i)], b),
    }
    _, peak = _peak(calls[fn])
    assert len(b.verts) == 400
    assert peak < 8e6, f"{peak / 1e6:.1f} MB"


def test_an_ssph_graph_over_budget_is_skipped_with_a_note_and_the_search_runs_on_edh(monkeypatch):
    """A replan around one cell: with the reduced graph's budget at 10 (segment, edge) pairs the
    SSPH is not built, the plan is the EDH search's own, and its diagnostics say why."""
    cfg = MptpConfig(safety_single_m=(1000.0,) * 3, sigma_front_mps=0.0, sigma_back_mps=0.0)
    storms = [StormSnapshot(0.0, (box(6000.0, -1500.0, 9000.0, 1500.0),), np.zeros((1, 2)))]

    def plan(c: MptpConfig) -> Plan:
        planner = MptpPlanner(Mission(np.array([[20_000.0, 0.0, 0.0]]), c.tas_mps, 500.0), c)
        return planner.plan(vehicle_state(0.0, np.zeros(2), 0.0, c.tas_mps), Threats(storms=storms), 0.0)

    full = plan(cfg)
    assert "search_note" not in full.diagnostics and (full.labels >= 0).any()
    edh = plan(cfg.with_(heuristic="edh"))
    monkeypatch.setattr(visibility, "GRAPH_PAIR_BUDGET", 10)
    capped = plan(cfg)
    note = str(capped.diagnostics["search_note"])
    assert note.startswith("ssph skipped, edh used: its reduced visibility graph tests more than 10 (segment, edge)")
    assert np.array_equal(capped.positions, edh.positions) and np.array_equal(capped.times, edh.times)
    assert capped.diagnostics["expanded"] == edh.diagnostics["expanded"]
