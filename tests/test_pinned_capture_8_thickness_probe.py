"""Pinned rule of the thickness probe (`capture.resolution.probe`), round eight: the medial voxels are those whose
distance to the outside is the largest of their 3 × 3 × 3 neighbourhood (the 26 neighbours and themselves),
so a thin plate joined to a thick block keeps its own medial voxels beside the block, on either side of it.

The probe's solid is given (the voxeliser `solid_voxels` is replaced by a hand-built solid). In a cross-section
(y, z), extended over the 4 voxels of x (the array's ends in x are not outside, so nothing varies along x):

- a block of 7 × 7 voxels, y = 3..9, z = 1..7: its centre (6, 4) lies 4 voxels from the outside and is its only
  medial voxel (thickness 2 · 4 − 1 = 7);
- a plate 3 voxels thick (z = 1..3) and 2 long, on the block's +y side (y = 10, 11) or its −y side (y = 1, 2),
  flush with its bottom. The plate's voxel next to the block at mid-height, (10, 2), is 2 voxels from the
  outside (z = 0, z = 4 and y = 12 are outside); none of its 26 neighbours is deeper (the block's corner
  column y = 9 is at most 2 deep there), so it is medial with thickness 2 · 2 − 1 = 3. Two voxels further
  back, the block's (8, 3) is √5 = 2.24 deep: a neighbourhood reaching two voxels back along −y would drop
  the plate's only medial voxel.

So the medial thicknesses are four 3s (the plate, one per x) and four 7s (the block): the 10th percentile is
3 voxels, the thin part is the plate. Without the plate's medial voxels it would read 7, the block.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture import resolution
from fracture_gs.capture.resolution import probe
from fracture_gs.io.gaussian_set import GaussianSet


def some_gaussians(n=20) -> GaussianSet:
    quats = torch.zeros(n, 4)
    quats[:, 0] = 1.0
    return GaussianSet(torch.rand(n, 3), quats, torch.full((n, 3), 0.01), torch.full((n,), 0.9), torch.zeros(n, 1, 3))


def block_with_plate(side: str) -> torch.Tensor:  # [4, 13, 9] bool
    solid = torch.zeros(4, 13, 9, dtype=torch.bool)
    solid[:, 3:10, 1:8] = True  # the 7 × 7 block
    if side == "+y":
        solid[:, 10:12, 1:4] = True
    elif side == "-y":
        solid[:, 1:3, 1:4] = True
    return solid


@pytest.mark.parametrize("side, voxels", [("+y", 3.0), ("-y", 3.0), ("none", 7.0)])
def test_a_plate_beside_a_block_is_the_thin_part_on_either_side(monkeypatch, side, voxels):
    """A 3-voxel plate joined to a 7-voxel block, on its +y or its −y side, is measured 3 voxels thick: its
    voxel beside the block is the deepest of its 3 × 3 × 3 neighbourhood, hence medial, and it is half the
    medial voxels (10th percentile: 3). The block alone measures 7. The solid fraction is the solid's voxels
    over the probe's 128³ (4 · (49 + 6) with a plate)."""
    monkeypatch.setattr(resolution, "solid_voxels", lambda gs, h, **kw: block_with_plate(side))
    size = 0.64
    h = size / 128
    thin, fraction = probe(some_gaussians(), size, 0.2, 0.01, 1)
    assert thin == pytest.approx(voxels * h, rel=1e-12)
    solid = 4 * (49 + (6 if side != "none" else 0))
    assert fraction == pytest.approx(solid / 128**3, rel=1e-12)
