"""The pairwise visibility tests of the MPTP (guidance/mptp/visibility.py) hold at most
MAX_PAIRS pairs at once: a free space with many obstacle corners costs time, not memory that
grows with the square of its corners (issue 20: a corridor_opens replan was killed at 22 GB)."""

import tracemalloc

import numpy as np
import pytest
import shapely
from shapely.geometry import box

from guidance.mptp import visibility
from guidance.mptp.visibility import boundary_of, first_hit, reduced_graph


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
