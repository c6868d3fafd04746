"""The fragment-aware overlap's hash tables (`sim.overlap_kernels.VoxelOverlap`): open addressing with linear
probing at load ≤ ½. Each particle adds at most one voxel and one (voxel, fragment) pair, so tables of at least
2·n slots (a power of two, the probe's mask) keep the load at ½ or less for n particles; they are the smallest
such power of two from 1,024 up. At the fullest a scene can make them (every particle in a voxel and a pair of
its own) the results still equal the torch twin's (`penetration.overlap_packed`) bit for bit."""

import torch

from fracture_gs.sim.diagnostics.overlap_kernels import VoxelOverlap
from fracture_gs.sim.diagnostics.penetration import overlap_packed


def test_tables_hold_twice_the_particles_in_the_smallest_power_of_two():
    """For n from 0 to 5,000 (both sides of 512 and of each power of two): capacity is a power of two, at least
    1,024 and 2·n, and half of it is below both bounds' maximum (not larger than needed); every table has it."""
    for n in (0, 1, 511, 512, 513, 1000, 1024, 1025, 2048, 2049, 5000):
        vo = VoxelOverlap(n, "cpu")
        cap = vo.capacity
        need = max(1024, 2 * max(n, 1))
        assert cap & (cap - 1) == 0, f"n = {n}: {cap} is not a power of two"
        assert cap >= need and cap // 2 < need, f"n = {n}: capacity {cap} for load ≤ ½ needs {need}"
        for name in ("pair_keys", "pair_count", "voxel_keys", "best", "level", "same", "neighbour"):
            assert getattr(vo, name).shape[0] == cap, name
        assert vo.voxel_of.shape[0] == n


def test_tables_at_their_fullest_give_the_twins_result():
    """A 14³ lattice of fragment 0, one particle per voxel of edge h, with a 6³ lattice of fragment 1 inside it
    (one particle per voxel too, in voxels fragment 0 also holds: ties go to the smaller id): as many voxels and
    pairs as particles allow. Crossing count, deepest crossing and pair depths equal the torch twin's exactly, and
    fragment 1's particles deep inside fragment 0 are found."""
    h = 1 / 64  # a power of two: voxel coordinates (x − lo) / h come out exact
    a = (torch.stack(torch.meshgrid(*[torch.arange(14)] * 3, indexing="ij"), -1).reshape(-1, 3) + 0.5) * h
    b = (torch.stack(torch.meshgrid(*[torch.arange(6)] * 3, indexing="ij"), -1).reshape(-1, 3) + 4.25) * h
    x = torch.cat([a, b]).float()
    frag = torch.cat([torch.zeros(len(a)), torch.ones(len(b))]).int()
    got = VoxelOverlap(len(x), "cpu").packed(x, frag, h, 2)
    assert torch.equal(got, overlap_packed(x, frag, h, 2))
    assert int(got[0]) == len(b) and float(got[2 + 1 * 2 + 0]) >= 4 * h, "fragment 1 lies deep inside 0"
