"""Unlabelled particles (fragment −1) take no part in the fragment-aware overlap (`sim.diagnostics.overlap_kernels`).

An unlabelled particle belongs to no piece: it must neither move the voxel lattice (the lowest *labelled* particle
fixes it), nor own or share a voxel, nor be scored as crossing into a piece, wherever it lies: inside a piece's
deepest voxel or below everything. `bin_particles` marks its voxel slot −1 and `score_particles` skips it. Here a
solid 5³-voxel block of fragment 0 is placed so that its centre voxel (erosion level 2) is the one the table holds
in slot 1, the slot a wrong mark (+1 for −1) would send an unlabelled particle to, and the centre voxel is inserted
first so that it keeps the slot it hashes to. The Warp tables must give the same numbers with and without the
unlabelled particles, and the torch twin's.
"""

from __future__ import annotations

import torch

from fracture_gs.sim.diagnostics.overlap_kernels import COORD_BITS, VoxelOverlap
from fracture_gs.sim.diagnostics.penetration import overlap_packed

H = 1.0 / 64  # voxel edge [m], a power of two: voxel coordinates come out exact


def _home(key: int, mask: int) -> int:
    """The first slot a voxel key probes: the top bits of key · ⌊2⁶⁴/φ⌋ (mod 2⁶⁴), as the table hashes."""
    return (((key * 11400714819323198485) % (1 << 64)) >> 33) & mask


def _key(c) -> int:
    return (c[0] << (2 * COORD_BITS)) | (c[1] << COORD_BITS) | c[2]


def _at(c):
    """A point inside the voxel of coordinates c, given the lowest labelled particle is in voxel (1, 1, 1)."""
    return [(a - 0.5) * H for a in c]


def _scene(mask: int):
    """(points, fragments, centre): the lowest labelled particle in voxel (1, 1, 1) (fragment 1, a lone voxel), then
    a 5³ block of fragment 0 whose centre voxel's key hashes to slot 1, centre first."""
    centre = next((10, cy, cz) for cy in range(10, 60) for cz in range(10, 60) if _home(_key((10, cy, cz)), mask) == 1)
    points, frags = [_at((1, 1, 1))], [1]
    r = range(-2, 3)
    block = [(centre[0] + i, centre[1] + j, centre[2] + k) for i in r for j in r for k in r]
    for c in dict.fromkeys([centre, *block]):  # 125 voxels, the centre first
        points.append(_at(c))
        frags.append(0)
    return points, frags, centre


def test_unlabelled_particles_change_nothing_even_in_a_pieces_deepest_voxel():
    """Without unlabelled particles nothing crosses (one piece, and a lone voxel of the other). Adding three
    unlabelled particles (one in the block's centre voxel, two below and beside every labelled particle) leaves
    every number as it was: no crossing, no depth, no pair; the centre voxel sits in slot 1 at erosion level 2."""
    vo = VoxelOverlap(200, "cpu")
    points, frags, centre = _scene(vo.capacity - 1)
    x = torch.tensor(points, dtype=torch.float32)
    fragment = torch.tensor(frags, dtype=torch.int32)
    base = vo.packed(x, fragment, H, 2)
    assert int(vo.voxel_keys[1]) == _key(centre) and int(vo.level[1]) == 2, "the centre voxel is slot 1's"
    assert base.tolist() == [0.0] * 6
    assert torch.equal(base, overlap_packed(x, fragment, H, 2))
    stray = torch.tensor([_at(centre), [-1.0, -1.0, -1.0], [-0.5, 0.3, 0.2]], dtype=torch.float32)
    xs = torch.cat([x, stray])
    fs = torch.cat([fragment, torch.full((3,), -1, dtype=torch.int32)])
    got = vo.packed(xs, fs, H, 2)
    assert int(vo.voxel_keys[1]) == _key(centre) and int(vo.level[1]) == 2, "the lattice did not move"
    assert got.tolist() == [0.0] * 6, "an unlabelled particle was scored"
    assert torch.equal(got, overlap_packed(xs, fs, H, 2))


def test_an_intruder_in_the_deepest_voxel_still_counts_beside_unlabelled_ones():
    """The same block with a fragment-1 particle in its centre voxel and an unlabelled one beside it: exactly one
    crossing, two voxels (2H) deep, fragment 1 inside fragment 0 (pair entry 2 + 1·K + 0), as the torch twin."""
    vo = VoxelOverlap(200, "cpu")
    points, frags, centre = _scene(vo.capacity - 1)
    points += [_at(centre), _at(centre)]
    frags += [1, -1]
    x = torch.tensor(points, dtype=torch.float32)
    fragment = torch.tensor(frags, dtype=torch.int32)
    got = vo.packed(x, fragment, H, 2)
    assert got.tolist() == [1.0, 2 * H, 0.0, 0.0, 2 * H, 0.0]
    assert torch.equal(got, overlap_packed(x, fragment, H, 2))
