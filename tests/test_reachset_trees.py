"""Reach sets (spec §4, T-RS-1..5, 8, 9): sizes, bounds per variant, combined union, ACAS-like."""

import numpy as np
import pytest

from avoidance.reachset.cache import reach_set
from avoidance.reachset.config import ExpansionConfig, GridConfig, MovementConfig, ReachSetConfig
from avoidance.reachset.grid import AvoidanceGrid
from avoidance.reachset.metrics import bounds, full_tree_size, trajectory_count
from avoidance.reachset.movement import MovementType as M
from avoidance.reachset.movement import build_primitive_table

GRID = AvoidanceGrid()
TABLE = build_primitive_table(MovementConfig())
VARIANTS = {
    "chaotic": (ReachSetConfig.single(ExpansionConfig.chaotic()), (2835, 28350)),
    "harmonic": (ReachSetConfig.single(ExpansionConfig.harmonic()), (2835, 3150)),
    "combined": (ReachSetConfig.combined(), (2835, 25550)),
}


def test_full_tree_sizes():
    assert full_tree_size(9, 10) == 3_922_632_451
    assert full_tree_size(9, 5) == 66_430


@pytest.mark.parametrize("name", VARIANTS)
def test_tree_size_within_bounds(name):
    cfg, expected = VARIANTS[name]
    assert bounds(cfg, GRID.cfg) == expected
    tree = reach_set(GRID, TABLE, cfg)
    assert trajectory_count(tree) <= expected[0] and tree.n_nodes <= expected[1]
    leaves = tree.leaves()
    assert (GRID.layer[tree.tip_cell[leaves]] == GRID.cfg.n_layers - 1).all()  # pruned to the final layer
    assert (tree.tip_cell[1:] >= 0).all() and (tree.cells >= 0).all()  # contained reach set
    assert np.all(np.diff(tree.depth) >= 0) and (tree.parent[1:] < np.arange(1, tree.n_nodes)).all()


def test_harmonic_is_smoother_than_chaotic():
    harmonic = reach_set(GRID, TABLE, VARIANTS["harmonic"][0])
    chaotic = reach_set(GRID, TABLE, VARIANTS["chaotic"][0])
    h, c = harmonic.leaves(), chaotic.leaves()
    assert harmonic.smoothness[h].mean() > chaotic.smoothness[c].mean()


def test_combined_is_union_with_mode_switch_cost():
    parts = [reach_set(GRID, TABLE, ReachSetConfig.single(p)) for p in ReachSetConfig.combined().parts]
    combined = reach_set(GRID, TABLE, ReachSetConfig.combined())
    keys = combined.buffers()
    assert set(keys) == set(parts[0].buffers()) | set(parts[1].buffers())
    assert len(keys) == len(set(keys))
    for n in (1, combined.n_nodes // 2, combined.n_nodes - 1):
        buf = keys[n]
        base = np.prod([1.2 if m not in (M.STRAIGHT, M.LEFT, M.RIGHT) else 1.0 for m in buf])
        smooth = sum(m == M.STRAIGHT for m in buf) / len(buf)
        assert combined.cost[n] == pytest.approx(base * (2 - smooth))


@pytest.mark.parametrize(
    "sep,allowed", [(("horizontal",), {M.STRAIGHT, M.LEFT, M.RIGHT}), (("vertical",), {M.STRAIGHT, M.UP, M.DOWN})]
)
def test_acas_like_buffers_stay_in_their_plane(sep, allowed):
    tree = reach_set(GRID, TABLE, ReachSetConfig.single(ExpansionConfig.acas(sep)))
    assert set(tree.movement[1:].tolist()) <= {int(m) for m in allowed}
    axis = 2 if sep == ("horizontal",) else 1
    np.testing.assert_allclose(tree.samples[:, :, axis], 0.0, atol=1e-12)


def test_uas_entry_leave_times():
    tree = reach_set(GRID, TABLE, VARIANTS["combined"][0])
    entry, leave = tree.uas_entry_leave()
    layer = GRID.layer
    passed = leave > 0
    assert (entry[passed] <= leave[passed]).all()
    # a 1 m/s vehicle cannot be in layer i before (i-1) s nor leave layer 1 after ~3 s
    assert (entry[passed] >= layer[passed] * 1.0 - 0.11).all()


def test_disk_cache_round_trip(tmp_path):
    cfg = ReachSetConfig.single(ExpansionConfig.harmonic(3))
    grid = AvoidanceGrid(GridConfig(n_layers=6, d_range=(0.0, 6.0)))
    first = reach_set(grid, TABLE, cfg, tmp_path)
    assert list(tmp_path.glob("*.npz"))
    from avoidance.reachset import cache

    cache._MEMORY.clear()
    again = reach_set(grid, TABLE, cfg, tmp_path)
    np.testing.assert_array_equal(first.parent, again.parent)
    np.testing.assert_allclose(first.samples, again.samples)
