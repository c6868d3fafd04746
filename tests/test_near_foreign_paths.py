"""`_Cells.near_foreign`, the first filter of the fragment-aware penetration measure: a particle is evaluated when
its cell or one of the 26 around it holds a particle of another fragment. Two paths compute it (a dense 3×3×3
max-pool over the occupied cells' bounding box, and binary searches over sorted cell keys for boxes too large
to hold densely); they must agree exactly, and both must follow the rule."""

import pytest
import torch

from fracture_gs.sim.diagnostics import penetration as P


def _both(cells, monkeypatch):
    dense = cells.near_foreign()
    monkeypatch.setattr(P, "DENSE_CELLS", 0)  # every box is "too large": the sorted-key path
    sparse = cells.near_foreign()
    monkeypatch.undo()
    return dense, sparse


def test_a_foreign_particle_in_the_next_cell_counts_and_two_cells_away_does_not(monkeypatch):
    """Cells of edge 1: fragment 0 at cells x = 0 and x = 5, fragment 1 at x = 1 (a face neighbour of the first)
    and fragment 1 at x = 7 (two cells from the second): the particles of x = 0 and x = 1 are near a foreign one,
    those of x = 5 and x = 7 are not; a diagonal (corner) neighbour counts like a face one."""
    x = torch.tensor(
        [[0.5, 0.5, 0.5], [1.5, 0.5, 0.5], [5.5, 0.5, 0.5], [7.5, 0.5, 0.5], [10.5, 0.5, 0.5], [11.5, 1.5, 1.5]],
        dtype=torch.float64,
    )
    fragment = torch.tensor([0, 1, 0, 1, 2, 0])
    cells = P._Cells(x, fragment, torch.zeros(3, dtype=torch.float64), 1.0)
    for got in _both(cells, monkeypatch):
        assert got.tolist() == [True, True, False, False, True, True]


def test_unlabelled_particles_count_as_a_fragment_of_their_own(monkeypatch):
    """An unlabelled particle (id −1) beside a labelled one makes both cells mixed, as the sorted-key path
    always read it (its minimum id differs from its maximum)."""
    x = torch.tensor([[0.5, 0.5, 0.5], [1.5, 0.5, 0.5], [4.5, 0.5, 0.5]], dtype=torch.float64)
    cells = P._Cells(x, torch.tensor([-1, 3, 3]), torch.zeros(3, dtype=torch.float64), 1.0)
    for got in _both(cells, monkeypatch):
        assert got.tolist() == [True, True, False]


@pytest.mark.parametrize("seed", range(6))
def test_the_dense_and_sorted_paths_agree_on_random_clouds(seed, monkeypatch):
    """Random clouds with up to five fragments, unlabelled particles and a region of one fragment only: the two
    paths give the same particles, and some but not all of them are near a foreign one."""
    g = torch.Generator().manual_seed(seed)
    n = 2500
    x = torch.rand(n, 3, generator=g, dtype=torch.float64) * torch.tensor([1.0, 0.5, 0.3], dtype=torch.float64)
    fragment = torch.randint(-1, 5, (n,), generator=g)
    fragment = torch.where(x[:, 0] < 0.5, torch.zeros_like(fragment), fragment)  # one piece alone on the left
    cells = P._Cells(x, fragment, x.min(0).values, 0.02 + 0.01 * seed)
    dense, sparse = _both(cells, monkeypatch)
    assert torch.equal(dense, sparse)
    assert 0 < int(dense.sum()) < n
