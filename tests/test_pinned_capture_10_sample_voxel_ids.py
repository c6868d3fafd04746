"""Pinned rule of particle sampling (`capture.sample.sample`), round ten: the voxel id of a surface Gaussian is a
one-to-one function of its voxel's three integer coordinates, however long the occupied block is along any one
axis. Round three's block (3 × 4 × 5) is shorter along x than along y, where an id mixing the axes wrongly (a
quotient instead of a product, or the spans swapped) can still happen to be one-to-one; here rods of 7 voxels
along each axis in turn, 2 and 3 across, make any such mix merge two voxels into one particle.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture.sample import sample
from fracture_gs.io.gaussian_set import GaussianSet

SPACING = 0.01  # m
PER_VOXEL = 3


def rod(span, first=(-4, 1, -2), seed=0):
    """PER_VOXEL surface Gaussians inside each voxel of a block of `span` voxels (10–90 % of the voxel on every
    axis) with distinct opacities; returns (set, index of the most opaque Gaussian of each voxel [V])."""
    g = torch.Generator().manual_seed(seed)
    voxels = torch.cartesian_prod(*[torch.arange(f, f + s) for f, s in zip(first, span)])  # [V, 3]
    vox = voxels.repeat_interleave(PER_VOXEL, 0)  # [S, 3]
    x = (vox.double() + 0.1 + 0.8 * torch.rand(len(vox), 3, generator=g, dtype=torch.float64)) * SPACING
    opacity = (torch.randperm(len(vox), generator=g).double() + 1) / (len(vox) + 1)  # all different, in (0, 1)
    best = opacity.reshape(-1, PER_VOXEL).argmax(1) + PER_VOXEL * torch.arange(len(voxels))  # [V]
    n = len(x)
    quats = torch.zeros(n, 4)
    quats[:, 0] = 1.0
    gs = GaussianSet(
        x.float(),
        quats,
        torch.full((n, 3), 0.001),
        opacity.float(),
        torch.zeros(n, 1, 3),
        interior=torch.zeros(n, dtype=torch.bool),
    )
    return gs, best


@pytest.mark.parametrize("span", [(7, 2, 3), (2, 7, 3), (3, 2, 7), (7, 3, 2), (2, 3, 7), (7, 7, 2)])
def test_every_voxel_of_a_long_rod_gets_its_own_particle(span):
    """A rod of voxels (7 along one axis, 2 and 3 across; and a 7 × 7 × 2 plate), 3 surface Gaussians in each:
    one particle per voxel, 42 (or 98), each the most opaque Gaussian of its voxel (in index order), and the note
    counts them."""
    gs, best = rod(span)
    carried, note = sample(gs, SPACING)
    c = carried.carrier
    assert c is not None
    voxels = span[0] * span[1] * span[2]
    assert c.particles.means.tolist() == gs.means[best.sort().values].tolist()
    assert note == (
        f"particles: {voxels} simulated ({voxels} of {len(gs)} surface Gaussians, one per 10 mm voxel, and 0 "
        f"interior), carrying all {len(gs)} Gaussians"
    )
