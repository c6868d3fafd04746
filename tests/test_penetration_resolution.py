"""The continuous fragment-aware penetration (`sim.penetration.surface_depth`) resolves depths well below
0.1Δx: two jittered blocks cut from one sample and pushed into each other by a known depth read that depth,
touching blocks read (almost) nothing, whatever the orientation, the sampling density of each piece or the
size of the pieces; the built-in plane-drop bar, cut in two and not moved, reads nothing."""

import pytest
import torch

from fracture_gs.io.gaussian_set import quat_to_matrix
from fracture_gs.sim.diagnostics.penetration import (
    SPACINGS,
    calibrate,
    depth_from_fraction,
    fraction_of_half_space,
    surface_depth,
    surface_penetration,
)

DX = 1 / 64


def stratified(lower, upper, spacing, g):
    """One point anywhere in each cell of edge `spacing` [m] of the box lower–upper (the asset sampler's
    jittered grid), float64 [M, 3]."""
    n = [max(1, round((b - a) / spacing)) for a, b in zip(lower, upper)]
    axes = [a + (torch.arange(m, dtype=torch.float64) + 0.5) * spacing for a, m in zip(lower, n)]
    x = torch.stack(torch.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    return x + (torch.rand(x.shape, generator=g, dtype=torch.float64) - 0.5) * spacing


def pushed_blocks(depth, rotation, seed, spacing=(0.5, 0.5), cells=(12, 10, 10)):
    """A block of `cells` Δx cut at its middle plane x = const into fragment 0 (x below, sampled at spacing[0]·Δx)
    and fragment 1 (above, spacing[1]·Δx), each a jittered grid starting at the cut; fragment 1 moved `depth`·Δx
    into fragment 0 along −x; the whole turned by `rotation`. Returns x [N, 3] float32, fragment [N] int32."""
    g = torch.Generator().manual_seed(seed)
    half = cells[0] * DX / 2
    a = stratified((0.0, 0.0, 0.0), (half, cells[1] * DX, cells[2] * DX), spacing[0] * DX, g)
    b = stratified((half, 0.0, 0.0), (2 * half, cells[1] * DX, cells[2] * DX), spacing[1] * DX, g)
    b[:, 0] -= depth * DX
    fragment = torch.cat([torch.zeros(len(a)), torch.ones(len(b))]).int()
    return (torch.cat([a, b]) @ rotation.T).float(), fragment


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


def test_calibration_finds_the_spacing_and_each_piece_density():
    """From positions alone: the spacing of a jittered grid of h = Δx/2 reads h within 3 %, the kernel radius is
    SPACINGS (4) spacings, and a piece sampled twice as densely gets twice the filled density (within 10 %)."""
    x, frag = pushed_blocks(0.0, torch.eye(3, dtype=torch.float64), 1)
    c = calibrate(x, frag)
    assert c["spacing"] / DX == pytest.approx(0.5, rel=0.03) and c["radius"] == pytest.approx(SPACINGS * c["spacing"])
    x, frag = pushed_blocks(0.0, torch.eye(3, dtype=torch.float64), 1, spacing=(0.5, 0.5 / 2 ** (1 / 3)))
    c = calibrate(x, frag)
    assert float(c["filled"][1] / c["filled"][0]) == pytest.approx(2.0, rel=0.1)


@pytest.mark.parametrize(
    "depth", [0.0, 0.1, pytest.param(0.05, marks=pytest.mark.slow), 0.25, pytest.param(0.5, marks=pytest.mark.slow)]
)
@pytest.mark.parametrize("spacing", [(0.5, 0.5), (0.5, 0.5 / 2 ** (1 / 3))], ids=["uniform", "b-2x-denser"])
def test_blocks_pushed_by_a_known_depth_read_it(depth, spacing):
    """Two halves pushed d = 0 … 0.5Δx into each other read d within ±0.05Δx (touching: below 0.05Δx, no
    particle 0.1Δx deep), also when one half is sampled twice as densely as the other: the measure resolves below
    0.1Δx, where the voxel occupancy could only say 0 or 0.6Δx, and weighs each piece by its own density (with
    one density for both, the denser half would read ≈ 0.6Δx deep when touching)."""
    x, frag = pushed_blocks(depth, torch.eye(3, dtype=torch.float64), seed=10, spacing=spacing, cells=(10, 8, 8))
    got = surface_penetration(x, frag, 0.1 * DX)
    assert abs(got["depth"] / DX - depth) <= 0.05, got["depth"] / DX
    if depth == 0.0:
        assert got["depth"] / DX < 0.05 and got["crossing"] == 0, got
    else:
        assert set(got["pairs"]) <= {(0, 1), (1, 0)} and got["pairs"]


def test_a_small_piece_resting_on_a_block_reads_no_depth():
    """A piece of 3 × 3 × 3 particles, far smaller than the kernel, sitting on a block's face reads below
    0.05Δx: its filled density comes from its spacing and the block's (its own particles never fill a kernel
    ball, and taken as filled they would put the block's face particles most of a radius deep)."""
    g = torch.Generator().manual_seed(4)
    block = stratified((0.0, 0.0, 0.0), (7 * DX, 7 * DX, 7 * DX), 0.5 * DX, g)
    chip = stratified((3 * DX, 3 * DX, 7 * DX), (4.5 * DX, 4.5 * DX, 8.5 * DX), 0.5 * DX, g)
    x = torch.cat([block, chip]).float()
    frag = torch.cat([torch.zeros(len(block)), torch.ones(len(chip))]).int()
    got = surface_penetration(x, frag, 0.1 * DX)
    assert got["depth"] / DX < 0.05 and got["crossing"] == 0, got
    x[len(block) :, 2] -= 0.5 * DX  # the chip pushed half a cell into the block is seen
    assert surface_penetration(x, frag, 0.1 * DX)["crossing"] > 0


def test_separated_blocks_read_zero():
    """Blocks a spacing apart read exactly 0: no candidate's other-fragment share reaches ½."""
    x, frag = pushed_blocks(-0.5, torch.eye(3, dtype=torch.float64), seed=1, cells=(10, 8, 8))
    depth, into = surface_depth(x, frag, calibrate(x, frag))
    assert float(depth.max()) == 0.0 and int(into.max()) == -1


@pytest.mark.slow
def test_deep_overlap_saturates_at_the_radius():
    """Pushed 4Δx into each other (beyond the radius R = 3Δx) the blocks read R, the lower bound the measure
    promises, with the scales calibrated while they touched (the tracker calibrates at the latch, before any
    overlap)."""
    touching = calibrate(*pushed_blocks(0.0, torch.eye(3, dtype=torch.float64), seed=2))  # as at the latch
    x, frag = pushed_blocks(4.0, torch.eye(3, dtype=torch.float64), seed=2)
    got = surface_penetration(x, frag, 0.1 * DX, touching)
    assert got["radius"] / DX == pytest.approx(3.0, rel=0.05)
    assert got["depth"] == pytest.approx(got["radius"], rel=1e-3) and got["crossing"] > 100


def test_the_plane_drop_bar_cut_in_two_reads_no_depth():
    """The Panel A bar (quick protocol), its two halves labelled as the oracle latches them and not yet
    moved, reads below 0.05Δx with no particle 0.1Δx deep — although its particles' stored volumes sum to ≈ 2.2×
    the capsule and the surface Gaussians crowd its skin: the measure weighs particles by each piece's density
    from positions, not by stored volumes (which read 0.24Δx and 25 crossings here)."""
    from fracture_gs.io.config import load_config
    from fracture_gs.paper.protocol import prepare
    from fracture_gs.pipeline import load_scene

    cfg = prepare(load_config("exp_table4a_plane_drop"), "quick").cfg
    gs = load_scene(cfg)
    got = surface_penetration(gs.means.float(), gs.labels.int(), 0.1 * cfg.sim.dx)
    assert sorted(torch.unique(gs.labels).tolist()) == [0, 1]
    assert got["depth"] / cfg.sim.dx < 0.05 and got["crossing"] == 0, got


@pytest.mark.slow
@pytest.mark.parametrize("depth", [0.0, 0.05, 0.1, 0.25, 0.5])
def test_turned_blocks_read_the_same_depth(depth):
    """The pushed blocks turned at random (three orientations, uniform and 2× denser halves) read d within
    ±0.05Δx: no preferred axis, no staircase."""
    for k, rot in enumerate(rotations(3, seed=5)[1:]):
        for spacing in ((0.5, 0.5), (0.5 / 2 ** (1 / 3), 0.5)):
            x, frag = pushed_blocks(depth, rot, seed=20 + k, spacing=spacing)
            got = surface_penetration(x, frag, 0.1 * DX)
            assert abs(got["depth"] / DX - depth) <= 0.05, (k, spacing, got["depth"] / DX)
            if depth == 0.0:
                assert got["crossing"] == 0, (k, got)
