"""The torch twin of the surface measure keeps its (query, fragment) sums dense up to DENSE_LIMIT entries and as
sorted unique keys beyond: two storages of the same sums, so the same depths and pieces, bit for bit.

`behind_surfaces_torch` adds each pair's kernel weight into its (query, other piece) entry; an entry over ½ is a
depth. Dense: one slot per (query, piece); sparse: one per pair key present. Both add the same weights in the
same order and list the entries ascending, so forcing the sparse storage (DENSE_LIMIT = 0) changes nothing."""

import torch

from fracture_gs.sim.diagnostics import penetration as pen


def _three_pressed(seed: int = 14):
    """Three jittered 6³ blocks (spacing 0.02 m) in a row along x, each pressed 2 spacings into the one before."""
    g = torch.Generator().manual_seed(seed)
    s, n = 0.02, 6
    parts, ids = [], []
    for k in range(3):
        axes = [torch.arange(n) * s + k * (n - 2) * s, torch.arange(n) * s, torch.arange(n) * s]
        p = torch.stack(torch.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3).double()
        parts.append(p + 0.2 * s * (torch.rand(p.shape, generator=g, dtype=torch.float64) - 0.5))
        ids.append(torch.full((len(p),), k, dtype=torch.long))
    return torch.cat(parts), torch.cat(ids)


def test_sparse_sums_give_the_dense_depths_and_pieces(monkeypatch):
    """Pressed blocks 0 | 1 | 2 (kernel radius 2.5 spacings, each piece's density one particle per spacing³):
    with the sums forced sparse every particle reads the same depth and the same piece as with dense sums; block 1
    lies behind both neighbours, its ends behind different pieces."""
    x, frag = _three_pressed()
    cal = {"radius": 0.05, "filled": torch.full((3,), 0.02**-3, dtype=torch.float64), "spacing": 0.05 / pen.SPACINGS}
    dense = pen.surface_depth(x, frag, cal, twin=True)
    monkeypatch.setattr(pen, "DENSE_LIMIT", 0)
    sparse = pen.surface_depth(x, frag, cal, twin=True)
    assert torch.equal(dense[0], sparse[0]) and torch.equal(dense[1], sparse[1])
    named = set(dense[1][frag == 1].tolist())
    assert {0, 2} <= named, "block 1 lies behind block 0 at one end and block 2 at the other"
    assert float(dense[0].max()) > 0.01, "pressed by two spacings (0.04 m): a depth of centimetres"
