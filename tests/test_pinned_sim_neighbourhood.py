"""`sim/neighbourhood.py` against hand-built scenes and a brute-force definition: the particle orders for
P2G (`cell`: by the stencil's base node, and by fragment within a cell; `interleaved`: the k-th particle of
every cell in cell order, then the (k+1)-th), the solo flags (no particle of another fragment within the
pooled cells around a particle, so none within the reach) and fragment mass centroids."""

import math

import pytest
import torch

from fracture_gs.errors import SimulationError
from fracture_gs.sim.neighbourhood import cell_order, fragment_centroids, solo_mask, solo_radius


def _column(z):
    """Particles at x = y = 0.5 and the given heights, in a 1 × 1 × 8 grid of unit cells."""
    z = torch.tensor(z, dtype=torch.float32)
    return torch.stack([torch.full_like(z, 0.5), torch.full_like(z, 0.5), z], 1)


def test_interleaved_order_takes_one_particle_per_cell_per_round():
    """Cells 0 (two particles), 2 and 5 (one each): the first round visits cells 0, 2, 5 in cell order,
    the second round the second particle of cell 0."""
    x = _column([5.5, 0.5, 2.5, 0.2])
    order = cell_order(x, (0.0, 0.0, 0.0), 1.0, (1, 1, 8), "interleaved")
    assert order.tolist() == [1, 2, 0, 3]


def test_cell_order_sorts_by_the_stencils_base_node():
    """`cell` mode orders by ⌊ξ − ½⌋: heights 0.6 and 1.4 share base node 0, 0.4 belongs to base node −1,
    1.6 to node 1; ties keep their input order."""
    x = _column([1.6, 1.4, 0.4, 0.6])
    order = cell_order(x, (0.0, 0.0, 0.0), 1.0, (1, 1, 8), "cell")
    assert order.tolist() == [2, 1, 3, 0]


def test_cell_order_groups_fragments_within_a_cell_and_never_across_cells():
    """With fragments, a cell's particles are grouped by fragment id, and a higher fragment id never moves a
    particle past the next cell: cell 1 fragment 0 stays after cell 0 fragment 1."""
    x = _column([1.5, 0.5, 0.3, 0.7])
    fragment = torch.tensor([0, 1, 0, 1], dtype=torch.int32)
    order = cell_order(x, (0.0, 0.0, 0.0), 1.0, (1, 1, 8), "interleaved", fragment)
    # (cell, fragment) of particles 0-3: (1, 0), (0, 1), (0, 0), (0, 1): round 0 visits (0, 0), (0, 1), (1, 0)
    sorted_keys = [(int(x[i, 2]), int(fragment[i])) for i in order.tolist()]
    assert order.tolist() == [2, 1, 0, 3]
    assert sorted_keys[:3] == [(0, 0), (0, 1), (1, 0)]
    order = cell_order(x, (0.0, 0.0, 0.0), 1.0, (1, 1, 8), "cell", fragment)  # base nodes: 1, 0, −1, 0
    assert order.tolist() == [2, 1, 3, 0]


def test_cell_order_refuses_an_unknown_mode():
    """A sort mode other than `cell` or `interleaved` is an error naming the mode."""
    with pytest.raises(SimulationError, match="'morton'"):
        cell_order(_column([0.5]), (0.0, 0.0, 0.0), 1.0, (1, 1, 8), "morton")


def _brute_solo(x, fragment, origin, dx, shape, r):
    """Solo by definition: no particle of another fragment in any 2Δx cell within r cells (clamped to the
    grid) of the particle's own."""
    h = 2.0 * dx
    dims = torch.tensor([int(math.ceil(s * dx / h)) + 1 for s in shape])
    cell = torch.floor((x.double() - torch.tensor(origin, dtype=torch.float64)) / h).long()
    cell = torch.minimum(cell.clamp_min(0), dims - 1)
    near = (cell[:, None, :] - cell[None, :, :]).abs().amax(-1) <= r  # [N, N]
    other = fragment[:, None] != fragment[None, :]
    return (~(near & other).any(1)).to(torch.int32)


def test_solo_flags_match_the_pooled_cell_definition_and_keep_other_fragments_out_of_reach(seed):
    """On random particles of three fragments (clustered, some near the origin corner and some outside the
    grid), solo_mask equals the brute-force definition over 2Δx cells, and no solo particle has a particle of
    another fragment within the reach."""
    g = torch.Generator().manual_seed(seed)
    dx, shape, origin = 0.125, (16, 12, 10), (0.0, 0.0, 0.0)
    centres = torch.tensor([[0.2, 0.2, 0.2], [1.2, 0.4, 0.6], [0.4, 1.2, 0.9]])
    fragment = torch.randint(0, 3, (300,), generator=g, dtype=torch.int32)
    x = (centres[fragment.long()] + 0.3 * torch.randn(300, 3, generator=g)).float()
    for reach in (0.3, 0.5, 1.0):
        r = solo_radius(reach, dx)
        got = solo_mask(x, fragment, origin, dx, shape, reach)
        assert torch.equal(got, _brute_solo(x, fragment, origin, dx, shape, r)), reach
        d = torch.cdist(x.double(), x.double())
        close_other = ((d < reach) & (fragment[:, None] != fragment[None, :])).any(1)
        assert not bool((got.bool() & close_other).any())
    assert 0 < int(solo_mask(x, fragment, origin, dx, shape, 0.3).sum()) < 300


def test_solo_radius_counts_cells_of_two_dx_up_to_six():
    """The solo neighbourhood is ⌈reach / 2Δx⌉ cells; beyond six cells nobody is solo (None)."""
    dx = 0.125
    assert solo_radius(0.25, dx) == 1 and solo_radius(0.26, dx) == 2
    assert solo_radius(1.5, dx) == 6 and solo_radius(1.51, dx) is None
    x = _column([0.5, 3.5]) * 0.125
    assert solo_mask(x, torch.tensor([0, 1]), (0.0, 0.0, 0.0), dx, (8, 8, 40), 1.51) is None


def test_fragment_centroids_are_mass_weighted_and_zero_when_empty():
    """Centroid of fragment k = Σ m x / Σ m over its particles; a fragment with no particle reads 0."""
    x = torch.tensor([[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [1.0, 2.0, 3.0]])
    m = torch.tensor([1.0, 3.0, 2.0])
    c = fragment_centroids(x, m, torch.tensor([0, 0, 2], dtype=torch.int32), 3)
    assert c.tolist() == [[3.0, 0.0, 0.0], [0.0, 0.0, 0.0], [1.0, 2.0, 3.0]]


def test_orders_match_a_lexicographic_sort_of_cells_on_an_offset_grid(seed):
    """On random particles inside an offset 3-D grid, `cell` order is the stable sort by (i, j, k) of the
    base node ⌊(x − origin)/Δx − ½⌋, and `interleaved` order lists round by round the r-th particle of every
    cell (cells ⌊(x − origin)/Δx⌋ in (i, j, k) order)."""
    g = torch.Generator().manual_seed(seed)
    origin, dx, shape = (-0.3, 0.2, 1.0), 0.1, (5, 6, 7)
    lo = torch.tensor(origin) + dx
    x = lo + torch.rand(200, 3, generator=g) * (torch.tensor(shape, dtype=torch.float32) - 3) * dx
    for mode, shift in (("cell", 0.5), ("interleaved", 0.0)):
        c = torch.floor((x.double() - torch.tensor(origin, dtype=torch.float64)) / dx - shift).long().tolist()
        by_cell = sorted(range(len(x)), key=lambda i: tuple(c[i]))
        if mode == "cell":
            want = by_cell
        else:
            rank, seen = {}, {}
            for i in by_cell:
                rank[i] = seen.get(tuple(c[i]), 0)
                seen[tuple(c[i])] = rank[i] + 1
            want = sorted(by_cell, key=lambda i: (rank[i], tuple(c[i])))
        assert cell_order(x, origin, dx, shape, mode).tolist() == want, mode


def test_fragment_centroids_clamp_ids_outside_the_count():
    """Ids at or beyond `count` are pooled into the last fragment (never written out of range)."""
    x = torch.tensor([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    c = fragment_centroids(x, torch.ones(2), torch.tensor([1, 5], dtype=torch.int32), 2)
    assert c.tolist() == [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
