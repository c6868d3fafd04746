"""The continuous fragment-aware penetration (`sim.penetration.surface_depth`) resolves depths well below
0.1Δx: two jittered blocks cut from one sample and pushed into each other by a known depth read that depth,
touching blocks read (almost) nothing, whatever the orientation."""

import pytest
import torch

from fracture_gs.io.gaussian_set import quat_to_matrix
from fracture_gs.sim.penetration import (
    depth_from_fraction,
    fraction_of_half_space,
    surface_depth,
    surface_penetration,
)

DX = 1 / 64


def pushed_blocks(depth, rotation, seed, spacing=0.5, cells=(12, 10, 10)):
    """One block of stratified samples (one point anywhere in each cell of edge spacing·Δx, as the asset
    sampler makes them) cut at its middle plane x = const into fragments 0 and 1; fragment 1 moved `depth`·Δx
    into fragment 0 along −x; the whole turned by `rotation`. Returns x [N, 3], fragment [N], volume [N]."""
    g = torch.Generator().manual_seed(seed)
    s = spacing * DX
    n = [round(c / spacing) for c in cells]
    axes = [(torch.arange(m, dtype=torch.float64) + 0.5) * s for m in n]
    x = torch.stack(torch.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    x = x + (torch.rand(x.shape, generator=g, dtype=torch.float64) - 0.5) * s
    fragment = (x[:, 0] >= cells[0] * DX / 2).long()
    x[fragment == 1, 0] -= depth * DX
    return (x @ rotation.T).float(), fragment.int(), torch.full((len(x),), s**3)


def rotations(n, seed=3):
    g = torch.Generator().manual_seed(seed)
    return [torch.eye(3, dtype=torch.float64)] + list(
        quat_to_matrix(torch.randn(n, 4, generator=g, dtype=torch.float64))
    )


def test_half_space_share_and_its_inverse():
    """The kernel's half-space share is ½ at the face, 0 and 1 a radius out and in, monotone; the inverse
    recovers u to 1e-9 (the depth map's arithmetic)."""
    u = torch.linspace(-1, 1, 201, dtype=torch.float64)
    f = fraction_of_half_space(u)
    assert float(f[0]) == pytest.approx(0.0, abs=1e-12) and float(f[-1]) == pytest.approx(1.0, abs=1e-12)
    assert float(f[100]) == pytest.approx(0.5, abs=1e-12) and bool((f[1:] > f[:-1]).all())
    torch.testing.assert_close(depth_from_fraction(f[1:-1]), u[1:-1], rtol=0, atol=1e-9)


@pytest.mark.parametrize("depth", [0.05, 0.1, 0.25, 0.5])
def test_blocks_pushed_by_a_known_depth_read_it(depth):
    """Two halves of one jittered block pushed d = 0.05 … 0.5Δx into each other read d within ±0.05Δx in
    three orientations (the axes and two random turns): the measure resolves below 0.1Δx, where the voxel
    occupancy could only say 0 or 0.6Δx."""
    for k, rot in enumerate(rotations(2)):
        x, frag, vol = pushed_blocks(depth, rot, seed=10 + k)
        got = surface_penetration(x, frag, vol, 0.1 * DX)
        assert abs(got["depth"] / DX - depth) <= 0.05, (k, got["depth"] / DX)
        assert set(got["pairs"]) <= {(0, 1), (1, 0)} and got["pairs"]


def test_touching_blocks_read_below_the_resolution():
    """The two halves of one block, touching but not pushed, read below 0.05Δx in four orientations and no
    particle lies 0.1Δx behind the other's surface (the false-positive case)."""
    for k, rot in enumerate(rotations(3, seed=5)):
        x, frag, vol = pushed_blocks(0.0, rot, seed=20 + k)
        got = surface_penetration(x, frag, vol, 0.1 * DX)
        assert got["depth"] / DX < 0.05 and got["crossing"] == 0, (k, got)


def test_separated_blocks_read_zero_and_deep_overlap_saturates_at_the_radius():
    """Blocks a spacing apart read exactly 0 (no candidate's other-fragment share reaches ½); pushed 4Δx into
    each other (beyond the radius R = 3Δx) the depth reads R, the lower bound the measure promises."""
    x, frag, vol = pushed_blocks(-0.5, torch.eye(3, dtype=torch.float64), seed=1)
    depth, into = surface_depth(x, frag, vol, 3 * DX)
    assert float(depth.max()) == 0.0 and int(into.max()) == -1
    x, frag, vol = pushed_blocks(4.0, torch.eye(3, dtype=torch.float64), seed=2)
    got = surface_penetration(x, frag, vol, 0.1 * DX, radius=3 * DX)
    assert got["depth"] == pytest.approx(3 * DX, rel=1e-3) and got["crossing"] > 100
