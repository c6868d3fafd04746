"""How a frame's numbers travel to the host: the tracker's `Packed` (one read per frame) and the overlap's packed
layout (`penetration.unpack_overlap`, `VoxelOverlap.packed`'s guards).

Packed: parts added in order come back under their names, flattened to float lists, in one read; nothing added
reads as {}. Overlap layout [2 + K·K]: (crossing count, deepest depth, depth of a inside b at 2 + a·K + b); the
unpacked pairs are the non-zero entries, keyed (a, b)."""

import pytest
import torch

from fracture_gs.sim.diagnostics.overlap_kernels import VoxelOverlap
from fracture_gs.sim.diagnostics.penetration import unpack_overlap
from fracture_gs.sim.diagnostics.tracker import Packed


def test_packed_reads_every_part_back_under_its_name_in_order():
    """A 0-d float, a [2, 2] int and a [3] float64 part come back flattened, as floats, under their own names."""
    p = Packed()
    assert p.read() == {}
    p.add("clamped", torch.tensor(7, dtype=torch.int32))
    p.add("block", torch.tensor([[1, 2], [3, 4]]))
    p.add("momentum", torch.tensor([0.5, -0.25, 8.0], dtype=torch.float64))
    assert p.read() == {"clamped": [7.0], "block": [1.0, 2.0, 3.0, 4.0], "momentum": [0.5, -0.25, 8.0]}


def test_unpack_overlap_decodes_counts_depth_and_nonzero_pairs():
    """K = 3: 5 crossings, deepest 0.75; entries 2 + 1·3 + 2 = 7 (1 inside 2) and 2 + 2·3 + 0 = 8 (2 inside 0) are
    non-zero, the rest (zeros) are not pairs."""
    values = [5.0, 0.75] + [0.0] * 9
    values[7], values[8] = 0.5, 0.75
    assert unpack_overlap(values, 3) == {"crossing": 5, "depth": 0.75, "pairs": {(1, 2): 0.5, (2, 0): 0.75}}


def test_voxel_tables_refuse_more_particles_or_fragments_than_they_hold():
    """Tables made for 10 particles take 10 and refuse 11, and fragment ids beyond 4096; fewer than two fragments or
    no particle is an all-zero result without a launch."""
    vo = VoxelOverlap(10, "cpu")
    x = torch.rand(11, 3)
    with pytest.raises(ValueError, match="holds 10 particles"):
        vo.packed(x, torch.zeros(11, dtype=torch.int32), 0.1, 2)
    with pytest.raises(ValueError, match="4096 fragments"):
        vo.packed(x[:10], torch.zeros(10, dtype=torch.int32), 0.1, 4097)
    two = torch.tensor([0] * 5 + [1] * 5, dtype=torch.int32)
    assert vo.packed(x[:10] + two[:, None] * 10.0, two, 0.1, 2).tolist() == [0.0] * 6, "10 fit; pieces apart"
    assert vo.packed(x[:10], torch.zeros(10, dtype=torch.int32), 0.1, 1).tolist() == [0.0, 0.0, 0.0]
    assert vo.packed(x[:0], torch.zeros(0, dtype=torch.int32), 0.1, 2).tolist() == [0.0] * 6
