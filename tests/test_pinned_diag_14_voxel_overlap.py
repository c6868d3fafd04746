"""The voxel-occupancy overlap (`penetration.fragment_overlap`, its Warp form `overlap_kernels.VoxelOverlap`) on a
scene whose answer is known by hand.

A block of fragment 0, two particles in every voxel of edge h = 1, owns its voxels; a single particle of another
fragment inside it does not change a voxel's owner. Erosion peels one layer of voxels per step, so a voxel k
layers in from the block's face (k = its smallest index distance to a face) survives exactly k steps: an intruder
there crosses by k·h. The measure is the same whichever axis is which (its voxel keys must not collide for a long
block in any direction) and for any number of fragments."""

import torch

from fracture_gs.sim.diagnostics.overlap_kernels import VoxelOverlap
from fracture_gs.sim.diagnostics.penetration import fragment_overlap, overlap_packed

NX, NY, NZ = 5, 11, 6  # voxels of the block: longer along y than along x


def _block(offset=(0.0, 0.0, 0.0)) -> torch.Tensor:  # [2·NX·NY·NZ, 3] two particles per unit voxel
    i = torch.stack(torch.meshgrid(*(torch.arange(n) for n in (NX, NY, NZ)), indexing="ij"), -1).reshape(-1, 3)
    i = i.double() + torch.tensor(offset, dtype=torch.float64)
    return torch.cat([i + 0.375, i + 0.625])


def _scene(intruders: int = 2):
    """The block with intruders of fragment 1 at voxel (2, 5, 2) (2 layers in) and of fragment 2 at (1, 8, 3)
    (1 layer in: one from the x face)."""
    at = torch.tensor([[2.5, 5.5, 2.5], [1.5, 8.5, 3.5]], dtype=torch.float64)[:intruders]
    x = torch.cat([_block(), at])
    fragment = torch.cat([torch.zeros(len(x) - intruders, dtype=torch.long), torch.arange(1, intruders + 1)])
    return x, fragment


def test_intruders_cross_by_their_layer_for_three_fragments():
    """Fragment 1 two layers deep (2h), fragment 2 one layer deep (h): 2 crossings, deepest 2h, and each pair's
    own depth — with three fragment ids as with two."""
    x, fragment = _scene()
    assert fragment_overlap(x, fragment, 1.0) == {"crossing": 2, "depth": 2.0, "pairs": {(1, 0): 2.0, (2, 0): 1.0}}
    x2, f2 = _scene(intruders=1)
    assert fragment_overlap(x2, f2, 1.0) == {"crossing": 1, "depth": 2.0, "pairs": {(1, 0): 2.0}}


def test_the_answer_does_not_depend_on_which_axis_is_which():
    """Every permutation of the axes (the long side along x, y or z) gives the same crossings and depths."""
    x, fragment = _scene()
    expected = {"crossing": 2, "depth": 2.0, "pairs": {(1, 0): 2.0, (2, 0): 1.0}}
    for order in ([0, 1, 2], [1, 0, 2], [2, 1, 0], [0, 2, 1], [1, 2, 0], [2, 0, 1]):
        assert fragment_overlap(x[:, order], fragment, 1.0) == expected, order


def test_the_warp_tables_read_the_same_numbers():
    """`VoxelOverlap.packed` (hash tables) gives the twin's packed numbers: count 2, depth 2, depth of 1 in 0 at
    2 + 1·3 + 0 and of 2 in 0 at 2 + 2·3 + 0."""
    x, fragment = _scene()
    out = VoxelOverlap(len(x), "cpu").packed(x.float(), fragment.int(), 1.0, 3)
    expected = torch.zeros(11, dtype=torch.float64)
    expected[0], expected[1], expected[2 + 3], expected[2 + 6] = 2.0, 2.0, 2.0, 1.0
    assert torch.equal(out, expected)


def test_a_crossing_particle_whose_voxel_sits_in_the_first_table_slot_counts():
    """Slot 0 of the voxel table is a slot like any other (−1 alone marks an unlabelled particle): a block placed so
    that the intruder's voxel hashes to slot 0 still reads its crossing (one layer in: depth h). A lone particle of
    fragment 0 at the corner fixes the voxel origin."""
    anchor = torch.tensor([[0.375, 0.375, 0.375]], dtype=torch.float64)
    intruder = torch.tensor([[2.5, 3.5, 11.5]], dtype=torch.float64)  # voxel (1, 2, 2) of the shifted block
    x = torch.cat([anchor, _block((1.0, 1.0, 9.0)), intruder])
    fragment = torch.zeros(len(x), dtype=torch.int32)
    fragment[-1] = 1
    vo = VoxelOverlap(len(x), "cpu")
    out = vo.packed(x.float(), fragment, 1.0, 2)
    assert int(vo.voxel_of[-1]) == 0, "the scene must put the intruder's voxel in slot 0 (hash changed?)"
    assert out.tolist() == [1.0, 1.0, 0.0, 0.0, 1.0, 0.0]
    assert fragment_overlap(x, fragment.long(), 1.0) == {"crossing": 1, "depth": 1.0, "pairs": {(1, 0): 1.0}}


def test_erosion_stops_after_max_depth_steps():
    """The depth is capped at max_depth·h: the intruder two layers deep reads h with max_depth = 1, 2h with 2 or
    more, and no crossing at all with 0 (no erosion step: no voxel counts as interior) — in the twin and in Warp."""
    x, fragment = _scene(intruders=1)
    vo = VoxelOverlap(len(x), "cpu")
    for steps, depth in ((0, 0.0), (1, 1.0), (2, 2.0), (5, 2.0)):
        pairs = {(1, 0): depth} if depth else {}
        want = {"crossing": int(depth > 0), "depth": depth, "pairs": pairs}
        assert fragment_overlap(x, fragment, 1.0, max_depth=steps) == want, steps
        packed = vo.packed(x.float(), fragment.int(), 1.0, 2, max_depth=steps).tolist()
        assert packed == [float(depth > 0), depth, 0.0, 0.0, depth, 0.0], steps


def test_a_non_finite_or_far_particle_changes_nothing_and_both_forms_agree():
    """A particle of fragment 1 at NaN, +∞ or 10³⁰ along x is binned into an edge voxel of its own: the two
    intruders still read 2h and h, no crossing is added, and the Warp tables give the twin's numbers bit for bit."""
    x, fragment = _scene()
    for bad in (float("nan"), float("inf"), 1e30):
        xx = torch.cat([x, torch.tensor([[bad, 1.5, 1.5]], dtype=torch.float64)])
        ff = torch.cat([fragment, torch.tensor([1])])
        assert fragment_overlap(xx, ff, 1.0) == {"crossing": 2, "depth": 2.0, "pairs": {(1, 0): 2.0, (2, 0): 1.0}}
        warp = VoxelOverlap(len(xx), "cpu").packed(xx.float(), ff.int(), 1.0, 3)
        assert torch.equal(warp, overlap_packed(xx.float(), ff.int(), 1.0, 3)), bad
