"""The fragment-aware penetration measure's torch twin skips the cells of a query's own piece
(`penetration._Cells.gather`'s `other_than`): a cell that holds only the query's fragment has no pair the measure
counts, and the pairs that remain keep their order, so every depth is the same to the last bit while the work near
a long contact face falls."""

from __future__ import annotations

import torch

from fracture_gs.sim.diagnostics import penetration as pen


def _pressed_blocks(seed: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Two jittered 16³ blocks of particles (spacing 0.02 m) pressed into each other along x by two spacings."""
    g = torch.Generator().manual_seed(seed)
    parts, ids = [], []
    for k, x0 in enumerate((0.0, 0.28)):
        axes = [torch.arange(16) * 0.02 + x0, torch.arange(16) * 0.02, torch.arange(16) * 0.02]
        p = torch.stack(torch.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3).double()
        parts.append(p + 0.004 * torch.rand(p.shape, generator=g, dtype=torch.float64))
        ids.append(torch.full((len(p),), k, dtype=torch.long))
    return torch.cat(parts), torch.cat(ids)


def test_skipping_own_cells_gives_the_same_depths_bit_for_bit(monkeypatch):
    """Depths and the piece each particle lies in, with the own-piece cells skipped, equal those of the full
    gather exactly, on pieces that overlap (some depth is non-zero), and the skip leaves out pairs."""
    x, frag = _pressed_blocks(0)
    cal = pen.calibrate(x[frag == 0], frag[frag == 0])  # the scales of one block alone, as at a latch
    cal["filled"] = cal["filled"].repeat(2)
    seen = {}
    gather = pen._Cells.gather

    def counting(self, coord, reach, other_than=None):
        out = gather(self, coord, reach, other_than)
        seen["skip" if other_than is not None else "all"] = seen.get("skip" if other_than is not None else "all", 0)
        seen["skip" if other_than is not None else "all"] += out[0].numel()
        return out

    monkeypatch.setattr(pen._Cells, "gather", counting)
    depth, into = pen.surface_depth(x, frag, cal, twin=True)
    skipped = seen.pop("skip")
    monkeypatch.setattr(pen._Cells, "gather", lambda self, coord, reach, other_than=None: counting(self, coord, reach))
    seen.clear()
    depth0, into0 = pen.surface_depth(x, frag, cal, twin=True)
    assert bool((depth0 > 0).any()), "the blocks overlap"
    assert torch.equal(depth, depth0) and torch.equal(into, into0)
    assert skipped < seen["all"], (skipped, seen)


def test_a_cell_of_the_querys_own_piece_is_left_out_and_a_mixed_one_kept():
    """`gather(..., other_than=f)`: particles in cells holding only fragment f are not returned for a query of f;
    a cell holding f and another fragment is returned whole; a query of another fragment gets them all."""
    x = torch.tensor([[0.05, 0.05, 0.05], [0.17, 0.05, 0.05], [0.18, 0.05, 0.05]], dtype=torch.float64)
    frag = torch.tensor([0, 0, 1])
    cells = pen._Cells(x, frag, x.min(0).values, 0.1)  # particle 0 alone in its cell; 1 and 2 share the next
    q = cells.coord[:1]  # a query in particle 0's cell
    _, j_all = cells.gather(q, 1)
    _, j_skip0 = cells.gather(q, 1, other_than=torch.tensor([0]))
    _, j_skip1 = cells.gather(q, 1, other_than=torch.tensor([1]))
    assert sorted(j_all.tolist()) == [0, 1, 2]
    assert sorted(j_skip0.tolist()) == [1, 2]
    assert sorted(j_skip1.tolist()) == [0, 1, 2]
