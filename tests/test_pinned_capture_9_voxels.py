"""`capture.sample` keeps the most opaque surface Gaussian of every voxel of the particle spacing, on a box of
voxels longer along y than along z: every voxel (cx, cy, cz) is its own, so no two voxels share a particle
whatever the box's proportions."""

from __future__ import annotations

import itertools

import torch

from fracture_gs.capture.sample import sample
from fracture_gs.io.gaussian_set import GaussianSet

SPACING = 0.01  # m


def test_one_particle_per_voxel_the_most_opaque_of_each():
    """3 × 5 × 2 voxels of 1 cm, two surface Gaussians in each (at ¼ and ¾ of the voxel, their opacities
    alternating which is larger): 30 particles of 60 Gaussians (below 80 %, so a carrier is built), exactly
    the more opaque Gaussian of every voxel, in index order, each carrying itself with no offset. A voxel key
    that mixed up the y and z extents (5 > 2) would merge voxels such as (0, 2, ·) and (1, 0, ·)."""
    means, opac, best = [], [], []
    for v, (cx, cy, cz) in enumerate(itertools.product(range(3), range(5), range(2))):
        for j, f in enumerate((0.25, 0.75)):
            means.append([(cx + f) * SPACING, (cy + f) * SPACING, (cz + f) * SPACING])
            high = j == v % 2
            opac.append(0.9 if high else 0.3)
            if high:
                best.append(2 * v + j)
    n = len(means)
    quats = torch.zeros(n, 4)
    quats[:, 0] = 1.0
    gs = GaussianSet(torch.tensor(means), quats, torch.full((n, 3), 0.002), torch.tensor(opac), torch.zeros(n, 1, 3))
    carried, note = sample(gs, SPACING)
    assert carried.carrier is not None, note
    particles = carried.carrier.particles
    assert len(particles) == 30
    assert torch.equal(particles.means, gs.means[torch.tensor(best)])
    index = carried.carrier.index
    assert index[torch.tensor(best)].tolist() == list(range(30))
    assert torch.all(carried.carrier.offset[torch.tensor(best)] == 0)
    assert "30 simulated (30 of 60 surface Gaussians" in note, note
