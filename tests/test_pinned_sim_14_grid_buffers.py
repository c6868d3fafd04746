"""The grid's buffers over a run (`sim.grid.fields.Grid`, `layout.pool_capacity`):

- the pool holds twice the expected multi-fragment nodes, a power of two, at least 256 rows;
- `ensure_pool` reallocates (zeroed, every claim free) only when the pool is too small or more than four times too
  large, and says whether it did; a single-field grid has no pool to size;
- `reset_claims` (between frames) frees every claim and empties the pool but keeps slot 0's accumulators and all
  velocities; `clear` (a substep) also zeroes slot 0's accumulators; `zero` (a box change) also the velocities;
- `rows_used` counts the used pool rows (0 for a single-field grid)."""

import torch

from fracture_gs.sim.grid.fields import Grid
from fracture_gs.sim.grid.layout import EMPTY_KEY, ROW_FLAG, pool_capacity


def _grid(slots=3):
    return Grid((0.0, 0.0, 0.0), 0.2, (5, 5, 5), "cpu", slots=slots)


def test_the_pool_holds_twice_the_rows_in_a_power_of_two_of_at_least_256():
    """0 → 256, 128 → 256, 129 → 512, 300 → 1024, 512 → 1024, 513 → 2048."""
    got = [pool_capacity(r) for r in (0, 128, 129, 300, 512, 513)]
    assert got == [256, 256, 512, 1024, 1024, 2048]


def test_the_pool_moves_only_when_too_small_or_over_four_times_too_large():
    """From 256 rows: 100 expected keeps it; 129 grows it to 512; 0 keeps 512 (2× too large); 1000 grows to
    2048; 200 (cap 512: exactly 4×) keeps it; 0 (cap 256: 8×) shrinks it to 256."""
    g = _grid()
    assert g.capacity == 256
    steps = [(100, False, 256), (129, True, 512), (0, False, 512), (1000, True, 2048), (200, False, 2048)]
    steps += [(0, True, 256)]
    for rows, moved, cap in steps:
        assert (g.ensure_pool(rows), g.capacity) == (moved, cap), rows


def test_a_moved_pool_starts_empty_with_every_claim_free():
    """After growing, the pool's keys are free, its slot owners −1, its band and accumulators 0, every owner word
    0, and the grid's view sees the new buffers (mask = capacity − 1)."""
    g = _grid()
    g._owner.fill_(1 | ROW_FLAG)
    g.key.fill_(3)
    g._mp.fill_(2.0)
    assert g.ensure_pool(300)
    assert g.capacity == 1024 and g.view.mask == 1023
    assert bool((g.key == EMPTY_KEY).all()) and bool((g.pool_owner == -1).all())
    assert g.pool_owner.numel() == 1024 * 2 and g.band.numel() == 1024 * 3
    assert not bool(g._mp.any()) and not bool(g._owner.any()) and not bool(g.band.any())
    assert g._mp.shape[0] == 125 + 1024 * 2


def test_a_single_field_grid_never_sizes_a_pool():
    """slots = 1: capacity 1 whatever is asked, never moved, no rows used."""
    g = _grid(slots=1)
    assert g.capacity == 1 and not g.ensure_pool(10**5) and g.capacity == 1
    assert int(g.rows_used()) == 0


def _filled():
    g = _grid()
    g._mp.fill_(1.0)
    g._vel.fill_(2.0)
    g._owner.fill_(1 | ROW_FLAG)
    g.key[:7] = torch.arange(7, dtype=torch.int32)
    g.pool_owner.fill_(1)
    g.band.fill_(3.0)
    return g


def test_reset_clear_and_zero_forget_exactly_what_they_promise():
    """Seven rows used. reset_claims: claims and pool freed, slot 0's (p, m) and every velocity kept. clear: slot 0's
    (p, m) zeroed too, velocities kept. zero: velocities zeroed too."""
    g = _filled()
    assert int(g.rows_used()) == 7
    n = g.n_nodes
    g.reset_claims()
    assert int(g.rows_used()) == 0 and bool((g.pool_owner == -1).all()) and not bool(g._owner.any())
    assert not bool(g.band.any()) and not bool(g._mp[n:].any())
    assert bool((g._mp[:n] == 1.0).all()) and bool((g._vel == 2.0).all())
    g = _filled()
    g.clear()
    assert int(g.rows_used()) == 0 and bool((g.pool_owner == -1).all()) and not bool(g._owner.any())
    assert not bool(g._mp.any()) and not bool(g.band.any()) and bool((g._vel == 2.0).all())
    g = _filled()
    g.zero()
    assert not bool(g._mp.any()) and not bool(g._vel.any()) and int(g.rows_used()) == 0


def test_contact_statistics_start_at_never_with_pair_rows_for_the_first_128_ids():
    """A new grid's totals are 0 but the first-contact time, which reads 'never' (1e30); one row of pair statistics
    per ordered pair of the first min(max_fragments, 128) ids, each 'never' in its time column and 0 elsewhere."""
    from fracture_gs.sim.physics.contact import N_PAIR_STATS, N_STATS, NEVER, PAIR_FIRST_T, STAT_FIRST_T

    never = float(torch.tensor(NEVER))
    for max_fragments, rows in ((5, 5), (128, 128), (4096, 128)):
        g = Grid((0.0, 0.0, 0.0), 0.2, (5, 5, 5), "cpu", slots=2, max_fragments=max_fragments)
        assert g.pair_fragments == rows and g.pair_stats.numel() == rows * rows * N_PAIR_STATS
        assert g.contact_stats.tolist() == [0.0] * STAT_FIRST_T + [never] + [0.0] * (N_STATS - STAT_FIRST_T - 1)
        pairs = g.pair_stats.view(-1, N_PAIR_STATS)
        assert bool((pairs[:, PAIR_FIRST_T] == never).all())
        assert not bool(pairs[:, PAIR_FIRST_T + 1 :].any())
