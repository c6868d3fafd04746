"""The surface measure's Warp walks read the sorted cell table only within its length.

Both kernels binary-search a cell's key in the V occupied keys; a key above every key gives index V, which is no
cell and must not be read. Here the tables are views into longer buffers whose entry just past the end fakes an
occupied cell (the query's neighbour, holding a particle of another piece next to the query): reading it would
find that particle. A walk that stays within the table finds only the query's own piece and reports nothing."""

from types import SimpleNamespace

import torch

from fracture_gs.sim.diagnostics import penetration as pen
from fracture_gs.sim.diagnostics import penetration_kernels as pk

SIZE = 0.01  # cell edge [m]


def _table_with_a_fake_entry_past_its_end():
    """Particle 0 (piece 0) alone in the table, cell (3, 3, 3); particle 1 (piece 1) 4 mm away, in no cell of the
    table, but named by the fake entry at index V = 1: the neighbour cell (3, 3, 4)."""
    x = torch.tensor([[0.0, 0.0, 0.0], [0.004, 0.0, 0.0]], dtype=torch.float64)
    frag = torch.tensor([0, 1])
    coord = torch.full((2, 3), 3, dtype=torch.long)  # ⌊(x − lo)/SIZE⌋ + 3 for both
    key = pen._keys(torch.tensor([[3, 3, 3], [3, 3, 4]]))
    buf = {
        "keys": key.clone(),
        "start": torch.tensor([0, 1]),
        "count": torch.tensor([1, 1]),
        "fmin": torch.tensor([0, 1]),
        "fmax": torch.tensor([0, 1]),
        "order": torch.tensor([0, 1]),
    }
    cells = SimpleNamespace(coord=coord, **{k: v[:1] for k, v in buf.items()})  # views: length 1, buffer 2
    assert all(v.data_ptr() == buf[k].data_ptr() for k, v in vars(cells).items() if k != "coord")
    return x, frag, cells


def test_the_near_walk_stops_at_the_end_of_the_table():
    """Particle 0's neighbours above its own cell search to index V: nothing there is read, so no other piece is
    near it (its only table entry is its own)."""
    x, frag, cells = _table_with_a_fake_entry_past_its_end()
    near = pk.near_another_piece_mask(x, frag, cells, torch.tensor([0]), SIZE, pen._BITS)
    assert near.tolist() == [False]


def test_the_depth_walk_stops_at_the_end_of_the_table():
    """The sums' walk over the cells within the kernel radius likewise: with a tiny filled density, any particle of
    piece 1 read would fill particle 0's ball (depth ≈ R); reading only the table gives depth 0, no piece."""
    x, frag, cells = _table_with_a_fake_entry_past_its_end()
    radius = 3 * SIZE
    ones = torch.ones(2, dtype=torch.float64)
    filled = torch.full((2,), 1e-3, dtype=torch.float64)
    offsets = pen._cube(3, x.device, ball=True)
    depth, into = pk.deepest_behind_surfaces(
        x, frag, ones, filled, radius, cells, offsets, torch.tensor([0]), pen._BITS, 8
    )
    assert depth.tolist() == [0.0] and into.tolist() == [-1]
