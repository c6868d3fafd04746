"""The fragment-aware overlap in Warp launches (`sim/diagnostics/overlap_kernels.py`) against its torch twin
(`penetration.overlap_packed`) and the plain-Python twin: the same crossing count, deepest crossing and
per-pair depths, exactly (integer counts and voxel levels times h, no rounding to differ)."""

import pytest
import torch
from test_many_fragments import _overlap_reference

from fracture_gs.sim.diagnostics.overlap_kernels import VoxelOverlap
from fracture_gs.sim.diagnostics.penetration import overlap_packed


def _pieces(seed: int, K: int, n: int, spread: float = 0.12):
    """K interpenetrating blobs of particles, 1 % of them labelled with another blob's id (intruders deep
    inside a piece) and 1 % unlabelled (−1)."""
    g = torch.Generator().manual_seed(seed)
    centres = 0.3 + 0.1 * torch.rand(K, 3, generator=g)
    frag = torch.randint(0, K, (n,), generator=g)
    x = centres[frag] + spread * (torch.rand(n, 3, generator=g) - 0.5)
    intruders = torch.rand(n, generator=g) < 0.01
    frag = torch.where(intruders, (frag + 1) % K, frag)
    frag[torch.rand(n, generator=g) < 0.01] = -1
    return x.float(), frag.int()


@pytest.mark.parametrize("seed", range(4))
def test_warp_overlap_equals_both_twins(seed, device):
    """Owner election (most particles, ties to the smaller id), six-neighbour erosion by levels and the
    particle scores agree bit for bit with the sorted-key torch twin and the dict-based Python twin."""
    K, h = 3 + seed, 0.02
    x, frag = _pieces(seed, K, 4000)
    got = VoxelOverlap(len(x), device).packed(x.to(device), frag.to(device), h, K).cpu()
    assert got[0] > 0, "the pieces interpenetrate"
    assert torch.equal(got, overlap_packed(x, frag, h, K))
    assert torch.equal(got, _overlap_reference(x, frag, h, K))


def test_warp_overlap_edge_cases(device):
    """Ids at or past K count as K − 1 (as in the twin); no labelled particle, one fragment, no particle
    give zeros; the tables are reused across calls and particle counts up to their size; a count past it
    is refused in one sentence."""
    vo = VoxelOverlap(3000, device)
    x, frag = _pieces(7, 4, 3000)
    frag = torch.where(frag == 3, torch.full_like(frag, 9), frag)  # ids past K = 4
    for n in (3000, 1200):
        got = vo.packed(x[:n].to(device), frag[:n].to(device), 0.02, 4).cpu()
        assert torch.equal(got, overlap_packed(x[:n], frag[:n], 0.02, 4))
    none = torch.full_like(frag, -1)
    assert torch.equal(vo.packed(x.to(device), none.to(device), 0.02, 4).cpu(), torch.zeros(18, dtype=torch.float64))
    assert torch.equal(vo.packed(x.to(device), frag.to(device), 0.02, 1).cpu(), torch.zeros(3, dtype=torch.float64))
    assert vo.packed(x[:0].to(device), frag[:0].to(device), 0.02, 4).abs().sum() == 0
    with pytest.raises(ValueError, match="holds 10 particles"):
        VoxelOverlap(10, device).packed(x.to(device), frag.to(device), 0.02, 4)


def test_warp_overlap_many_fragments(device):
    """K = 70 separate cubes of particles (pair slots up to 70², fragment ids over 64), 1 % of each cube's
    particles labelled with the next cube's id: the same numbers as the twin, and the intruders land in
    their own (a, a + 1) entries."""
    K, h, per = 70, 0.01, 600
    g = torch.Generator().manual_seed(5)
    ijk = torch.stack(torch.meshgrid(torch.arange(5), torch.arange(5), torch.arange(3), indexing="ij"), -1)
    centres = 0.1 * ijk.reshape(-1, 3)[:K].float()
    frag = torch.arange(K).repeat_interleave(per)
    x = centres[frag] + 0.05 * (torch.rand(K * per, 3, generator=g) - 0.5)
    label = torch.where(torch.rand(K * per, generator=g) < 0.01, (frag + 1) % K, frag).int()
    got = VoxelOverlap(len(x), device).packed(x.to(device), label.to(device), h, K).cpu()
    assert torch.equal(got, overlap_packed(x, label, h, K))
    pairs = got[2:].view(K, K)
    hit = torch.nonzero(pairs > 0)
    assert len(hit) > K // 2 and bool(((hit[:, 1] + 1) % K == hit[:, 0]).all()), "intruder a inside cube a − 1"
