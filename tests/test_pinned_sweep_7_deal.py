"""`sweep.driver.deal`, the longest-processing-time plan of pending cells over ranks: only the ratios of the cost
estimates matter (`Cell.cost`), so the same costs in any unit (2⁻⁷⁰ s to 2²⁰ s, powers of two so every sum is
exact) give the same plan; the plan is the LPT one worked out by hand (longest first to the least-loaded rank, ties
to the lower rank and the lower cell index, each rank's cells then in index order); equal costs go round-robin."""

from __future__ import annotations

import pytest

from fracture_gs.sweep.driver import deal
from fracture_gs.sweep.expansion import Cell


def cells(costs) -> list[Cell]:
    return [Cell(i, f"{i:012x}", "scene", {"i": i}, {}, ("t",), cost=c) for i, c in enumerate(costs)]


COSTS = [3.0, 7.0, 2.0, 5.0, 2.0, 4.0, 1.0]
# by hand, 2 ranks: 7 (cell 1) → r0 [7]; 5 (3) → r1 [5]; 4 (5) → r1 [9]; 3 (0) → r0 [10]; 2 (2) → r1 [11];
# 2 (4) → r0 [12]; 1 (6) → r1 [12]
LPT_2 = [[0, 1, 4], [2, 3, 5, 6]]
# 3 ranks: 7 → r0 [7]; 5 → r1 [5]; 4 → r2 [4]; 3 → r2 [7]; 2 (2) → r1 [7]; 2 (4) → r0 [9] (tie 7/7/7: lowest rank);
# 1 → r1 [8] (r1 and r2 at 7: lower rank)
LPT_3 = [[1, 4], [2, 3, 6], [0, 5]]


@pytest.mark.parametrize("scale", [2.0**-70, 2.0**-10, 1.0, 2.0**20])
def test_the_plan_depends_on_cost_ratios_not_their_unit(scale):
    """LPT by hand on costs 3, 7, 2, 5, 2, 4, 1: two ranks get cells {0, 1, 4} and {2, 3, 5, 6} (loads 12 and 12),
    three ranks {1, 4}, {2, 3, 6}, {0, 5}; the same costs times 2⁻⁷⁰ (a cell estimated at nothing), 2⁻¹⁰ or 2²⁰ deal
    the same (each rank's load starts at zero, so a tiny estimate still counts)."""
    scaled = cells([c * scale for c in COSTS])
    assert deal(scaled, 2) == LPT_2
    assert deal(scaled, 3) == LPT_3


@pytest.mark.parametrize("cost", [2.0**-70, 1.0, 2.0**30])
def test_equal_costs_go_round_robin_at_every_scale(cost):
    """Seven cells of one equal cost on three ranks go cell j → rank j mod 3, whatever that cost is."""
    assert deal(cells([cost] * 7), 3) == [[0, 3, 6], [1, 4], [2, 5]]


def test_one_rank_gets_everything_and_more_ranks_than_cells_leave_some_idle():
    """One rank holds every pending cell in index order; with more ranks than cells each cell gets a rank of its
    own, the longest to rank 0, and the spare ranks get none; no pending cells, empty lists."""
    assert deal(cells(COSTS), 1) == [list(range(7))]
    assert deal(cells([1.0, 3.0]), 4) == [[1], [0], [], []]
    assert deal([], 2) == [[], []]
