"""Pinned rules of particle sampling (`capture.sample.sample`), round three: one particle per occupied voxel of
the spacing, the most opaque surface Gaussian of that voxel, voxels told apart on every axis (also at negative
coordinates), every interior particle kept and carrying itself, every surface Gaussian carried by its nearest
particle with its exact offset; a set with at least 80 % as many particles as Gaussians is simulated whole,
and both notes state the counts and the spacing in millimetres.

Unit-level calls on hand-built Gaussian sets whose voxels are known.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture.sample import sample
from fracture_gs.io.gaussian_set import GaussianSet


def gaussian_set(means, opacities, interior=None) -> GaussianSet:
    x = torch.as_tensor(means, dtype=torch.float32)
    n = len(x)
    quats = torch.zeros(n, 4)
    quats[:, 0] = 1.0
    op = torch.as_tensor(opacities, dtype=torch.float32)
    inner = None if interior is None else torch.as_tensor(interior, dtype=torch.bool)
    return GaussianSet(x, quats, torch.full((n, 3), 0.001), op, torch.zeros(n, 1, 3), interior=inner)


SPACING = 0.01  # m
FIRST = (2, -3, 7)  # the lowest voxel's integer coordinates (negative on y)
SPAN = (3, 4, 5)  # voxels along x, y, z: a different count on each axis
PER_VOXEL = 5


def block():
    """PER_VOXEL surface Gaussians inside each voxel of a 3 × 4 × 5 block (well inside: 10–90 % of the voxel on
    every axis), with distinct random opacities, then 10 interior particles; returns (set, voxel of each
    surface Gaussian [S, 3], index of the most opaque Gaussian of each voxel)."""
    g = torch.Generator().manual_seed(3)
    voxels = torch.cartesian_prod(*[torch.arange(f, f + s) for f, s in zip(FIRST, SPAN)])  # [V, 3]
    vox = voxels.repeat_interleave(PER_VOXEL, 0)  # [S, 3]
    x = (vox.double() + 0.1 + 0.8 * torch.rand(len(vox), 3, generator=g, dtype=torch.float64)) * SPACING
    opacity = (torch.randperm(len(vox), generator=g).double() + 1) / (len(vox) + 1)  # all different, in (0, 1)
    best = opacity.reshape(-1, PER_VOXEL).argmax(1) + PER_VOXEL * torch.arange(len(voxels))  # [V]
    inner = (torch.tensor(FIRST).double() + 1.5 + torch.rand(10, 3, generator=g, dtype=torch.float64)) * SPACING
    means = torch.cat([x, inner])
    opac = torch.cat([opacity, torch.full((10,), 0.5, dtype=torch.float64)])
    interior = torch.cat([torch.zeros(len(x), dtype=torch.bool), torch.ones(10, dtype=torch.bool)])
    return gaussian_set(means, opac, interior), best


def test_one_particle_per_voxel_is_its_most_opaque_gaussian():
    """60 voxels of 5 surface Gaussians (3 × 4 × 5 voxels, so a voxel id must combine all three axes without
    collisions) and 10 interior particles: the simulated set is the most opaque Gaussian of each voxel (in index
    order) followed by the 10 interior particles, 70 in all."""
    gs, best = block()
    carried, _ = sample(gs, SPACING)
    c = carried.carrier
    assert c is not None
    chosen = torch.cat([best.sort().values, torch.arange(300, 310)])
    assert len(c.particles) == 70
    assert torch.equal(c.particles.means, gs.means[chosen])
    assert torch.equal(c.particles.opacities, gs.opacities[chosen])
    assert torch.equal(c.particles.interior, gs.interior[chosen])


def test_every_gaussian_rides_its_nearest_particle_and_interior_particles_carry_themselves():
    """Each surface Gaussian is carried by its nearest particle (brute force over all 70), with offset x_g − x_a;
    each interior particle is carried by itself (offset 0); the particles carry themselves too; the drawn set
    keeps every Gaussian."""
    gs, _ = block()
    carried, _ = sample(gs, SPACING)
    c = carried.carrier
    assert len(carried) == len(gs) and torch.equal(carried.means, gs.means)
    px = c.particles.means.double()
    d = torch.cdist(gs.means.double(), px)  # [310, 70]
    surface = torch.arange(300)
    assert torch.equal(c.index[surface], d[surface].argmin(1))
    assert torch.equal(c.index[300:], torch.arange(60, 70))
    want = (gs.means.double() - px[c.index]).float()
    assert float((c.offset - want).abs().max()) <= 1e-7
    assert float(c.offset[300:].abs().max()) == 0.0
    assert float(d.min(1).values.max()) < 3**0.5 * SPACING  # a particle in every occupied voxel


def test_sampled_note_counts_particles_surface_and_interior():
    """The note of a sampled set reads its particle count, how many surface Gaussians became particles, the voxel
    in millimetres, the interior count and the surface Gaussians it carries."""
    gs, _ = block()
    _, note = sample(gs, SPACING)
    assert note == (
        "particles: 70 simulated (60 of 300 surface Gaussians, one per 10 mm voxel, and 10 interior), "
        "carrying all 300 Gaussians"
    )


def line_set(voxels_per_gaussian, interior=0, spacing=0.0999):
    """Surface Gaussians along x, the i-th in voxel voxels_per_gaussian[i] (centred, nudged apart so none
    coincide), then `interior` interior particles."""
    v = torch.tensor(voxels_per_gaussian, dtype=torch.float64)
    nudge = 0.01 * torch.arange(len(v), dtype=torch.float64)
    x = torch.zeros(len(v) + interior, 3, dtype=torch.float64)
    x[: len(v), 0] = (v + 0.3 + nudge) * spacing
    x[len(v) :, 0] = (torch.arange(interior, dtype=torch.float64) + 0.5) * spacing
    x[:, 1:] = 0.5 * spacing
    flags = [False] * len(v) + [True] * interior
    return gaussian_set(x, torch.linspace(0.2, 0.9, len(x)), flags)


@pytest.mark.parametrize(
    "voxels, interior, whole",
    [
        ([0, 0, 1, 1, 2, 3, 4, 5, 6, 7], 0, True),  # 8 particles for 10 Gaussians: exactly 80 %
        ([0, 0, 0, 1, 1, 2, 3, 4, 5, 6], 0, False),  # 7 of 10: sampled
        ([0, 0, 1, 1, 2, 3, 4, 5], 2, True),  # 6 voxels + 2 interior = 8 of 10: whole
        ([0, 0, 0, 1, 1, 2, 3, 4], 2, False),  # 5 + 2 = 7 of 10: sampled
    ],
)
def test_a_set_with_80_percent_as_many_particles_as_gaussians_is_simulated_whole(voxels, interior, whole):
    """When the particles sampling would keep (one per surface voxel plus every interior particle) are at least
    80 % of the Gaussians, the set is returned as it is, every Gaussian a particle (exactly 8 of 10 counts, and
    interior particles count); below that it is sampled. The whole set's note reads its size and the spacing in
    millimetres (99.9 mm here)."""
    gs = line_set(voxels, interior)
    out, note = sample(gs, 0.0999)
    if whole:
        assert out is gs and out.carrier is None
        assert note == "particles: all 10 Gaussians simulated (no denser than 99.9 mm spacing)"
    else:
        assert out.carrier is not None
        assert len(out.carrier.particles) == len(set(voxels)) + interior
        assert "one per 99.9 mm voxel" in note


def test_an_interior_particle_carries_itself_even_where_a_surface_particle_coincides():
    """An interior fill particle lying exactly on a surface particle (distance 0 to both) is carried by itself,
    not by the surface one: its carrier index is its own row among the particles."""
    gs = line_set([0, 0, 0, 1, 1, 1, 2, 2, 2, 3, 3, 3], interior=0)
    x = torch.cat([gs.means, gs.means[:3]])  # three interior particles on the first voxel's Gaussians
    flags = [False] * 12 + [True] * 3
    both = gaussian_set(x, torch.cat([gs.opacities, torch.full((3,), 0.5)]), flags)
    carried, _ = sample(both, 0.0999)
    c = carried.carrier
    assert len(c.particles) == 4 + 3
    assert c.index[12:].tolist() == [4, 5, 6]
    assert float(c.offset[12:].abs().max()) == 0.0
