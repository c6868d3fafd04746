"""The fragment-aware overlap's hash probe (`sim.overlap_kernels.probe`) tells an absent face neighbour apart
from every table slot: a voxel on its piece's surface (a face neighbour missing) is never interior, at erosion
level 0, wherever its key lands in the table. Lone voxels are placed at keys whose first probe (Fibonacci
hashing, `home`) is slot 0, 1, 2 or 3, the slots a wrong "absent" answer could point at; each holds one particle
of fragment 0 and one of fragment 1 (a tie: fragment 0 owns it). None of the fragment-1 particles may count as
inside fragment 0, while one at the centre of a solid 5³-voxel block of fragment 0 counts, two voxels deep
(levels: 0 on the block's faces, 1 inside, 2 at the centre). The Warp tables must give the torch twin's numbers.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.sim.diagnostics.overlap_kernels import COORD_BITS, VoxelOverlap
from fracture_gs.sim.diagnostics.penetration import fragment_overlap, overlap_packed

H = 1.0 / 64  # voxel edge [m], a power of two: voxel coordinates come out exact


def _home(key: int, mask: int) -> int:
    """The first slot a key probes: the top bits of key · ⌊2⁶⁴/φ⌋ (mod 2⁶⁴), as the table hashes."""
    return (((key * 11400714819323198485) % (1 << 64)) >> 33) & mask


def _keys_in_slots(slots, mask):
    """Voxel coordinates (cx = 3, cy, cz in 3 … 59) whose key's first probe is each of `slots`."""
    found = {}
    for cy in range(3, 60):
        for cz in range(3, 60):
            s = _home((3 << (2 * COORD_BITS)) | (cy << COORD_BITS) | cz, mask)
            if s in slots and s not in found:
                found[s] = (3, cy, cz)
    assert sorted(found) == sorted(slots)
    return list(found.values())


def _at(c):
    """A point in the voxel of coordinates c, given the scene's lowest particle is in voxel (1, 1, 1)."""
    return [(a - 0.5) * H for a in c]


def test_surface_voxels_are_never_interior_whichever_slot_they_hash_to():
    """Four lone voxels (first probes in slots 0-3) and a 5³ block with a fragment-1 particle at its centre:
    one crossing particle, 2 voxels (2H) deep, fragment 1 inside fragment 0 only; equal to the torch twin."""
    block = [(40 + i, 40 + j, 40 + k) for i in range(5) for j in range(5) for k in range(5)]
    points, frags = [_at((1, 1, 1))], [0]  # the scene's lowest corner: voxel (1, 1, 1)
    for c in block:
        points.append(_at(c))
        frags.append(0)
    points.append(_at((42, 42, 42)))
    frags.append(1)
    n_lone = 0
    vo = VoxelOverlap(len(points) + 8, "cpu")
    for c in _keys_in_slots([0, 1, 2, 3], vo.capacity - 1):
        points += [_at(c), _at(c)]
        frags += [0, 1]
        n_lone += 1
    x = torch.tensor(points, dtype=torch.float32)
    fragment = torch.tensor(frags, dtype=torch.int32)
    got = vo.packed(x, fragment, H, 2)
    assert torch.equal(got, overlap_packed(x, fragment, H, 2))
    assert n_lone == 4 and int(got[0]) == 1, "only the block's centre particle is inside fragment 0"
    assert float(got[1]) == pytest.approx(2 * H, rel=1e-12)
    assert fragment_overlap(x, fragment, H) == {"crossing": 1, "depth": pytest.approx(2 * H), "pairs": {(1, 0): 2 * H}}
    assert got[2:].tolist() == [0.0, 0.0, pytest.approx(2 * H), 0.0]  # pair (a, b) at 2 + a·K + b
