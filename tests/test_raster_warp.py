"""The Warp rasterizer (`render/raster_kernels.py`, backend "warp"): the compositing rules of `render/splat.py`'s
docstring against the float64 per-pixel reference, the torch backend and hand-computed pixels, its tile lists
against the torch ones, and the backend choice. Random scenes draw a fresh seed (FGS_SEED reproduces one)."""

from __future__ import annotations

import math

import pytest
import torch
from test_render import _threshold_ambiguous, fresh_seed, random_rotations, random_scene
from torch.testing import assert_close

from fracture_gs.errors import ConfigError, RenderError
from fracture_gs.io.config import apply_overrides, find_config, load_config
from fracture_gs.render import look_at, render, render_reference
from fracture_gs.render.raster_kernels import tile_lists
from fracture_gs.render.splat import (
    TILE_CPU,
    Projection,
    _depth_order,
    _tile_intersections,
    project_gaussians,
    rasterize_tiles,
    rasterize_warp,
)

EYE = (0.05, -2.0, 0.3)


def _reference_scene(g, n=160):
    """`test_render`'s reference scene: random Gaussians, an opaque stack on the view axis (its pixels stop
    early), some behind the camera, some big and soft."""
    means, cov, _, opac = random_scene(n, g, spread=0.35, scale=0.05)
    cols = torch.rand(n, 3, generator=g)
    eye = torch.tensor(EYE)
    means[:12] = 0.3 * eye + 0.003 * torch.randn(12, 3, generator=g)
    cov[:12] = 0.04**2 * torch.eye(3)
    opac[:12] = 0.99
    means[12:20, 1] = -2.5
    cov[20:30] *= 30.0
    return means, cov, cols, opac


@pytest.mark.parametrize("mode", ["classic", "antialiased"])
def test_warp_backend_matches_float64_reference(mode):
    """Warp rasterizer vs the per-pixel float64 reference, with the torch backend's tolerances: ≤ 1e-4 everywhere
    in float32 except at most 5 pixels where a threshold decision (α vs 1/255, T vs 1e-4) lies within float32
    rounding of its boundary (each verified to be such a pixel), and ≤ 1e-10 in float64."""
    seed, g = fresh_seed()
    means, cov, cols, opac = _reference_scene(g)
    cam = look_at(EYE, (0, 0, 0), (0, 0, 1), 45, 61, 45)  # sizes not multiples of the tile
    bg = (0.2, 0.6, 1.0)
    ref = render_reference(means, cov, cols, opac, cam, bg, mode)
    assert (ref.alpha > 0.999).any() and (ref.alpha < 0.5).any(), f"seed {seed}: scene lacks stops/background"
    msg = lambda m: f"seed {seed} {mode}: {m}"  # noqa: E731
    out64 = render(means.double(), cov.double(), cols.double(), opac.double(), cam, bg, "warp", mode)
    assert out64.backend == "warp" and out64.image.dtype == torch.float64
    assert_close(out64.image, ref.image, rtol=0, atol=1e-10, msg=msg)
    assert_close(out64.alpha, ref.alpha, rtol=0, atol=1e-10, msg=msg)
    out = render(means, cov, cols, opac, cam, bg, "warp", mode)
    assert out.image.dtype == torch.float32 and out.image.shape == (45, 61, 3) and out.alpha.shape == (45, 61)
    err = torch.maximum((out.image.double() - ref.image).abs().amax(-1), (out.alpha.double() - ref.alpha).abs())
    bad = torch.nonzero(err > 1e-4).tolist()
    assert len(bad) <= 5, msg(f"{len(bad)} pixels over 1e-4, max {err.max():.2e}")
    assert all(_threshold_ambiguous(means, cov, opac, cam, mode, bad)), msg(f"pixels {bad} differ by {err.max():.2e}")


def _needles_and_discs(g, n=300):
    """Strongly anisotropic Gaussians (axis ratios up to 1:40) in random orientations."""
    means, _, _, opac = random_scene(n, g, spread=0.3)
    scales = torch.tensor([0.002, 0.08, 0.08]).repeat(n, 1)  # discs
    scales[::2] = torch.tensor([0.002, 0.002, 0.1])  # needles
    M = random_rotations(n, g).float() * scales[:, None, :]
    return means, M @ M.transpose(1, 2), torch.rand(n, 3, generator=g), opac


def _scene(kind: str, g):
    """(means, covariances, colours, opacities, mode) of one comparison scene."""
    if kind == "random":
        means, cov, _, opac = random_scene(400, g, spread=0.4, scale=0.05)
        return means, cov, torch.rand(400, 3, generator=g), opac, "classic"
    if kind == "anisotropic":
        return (*_needles_and_discs(g), "classic")
    if kind == "early_stop":  # many nearly opaque Gaussians in depth: most pixels stop long before the last
        means, cov, _, opac = random_scene(500, g, spread=0.15, scale=0.06)
        return means, cov, torch.rand(500, 3, generator=g), 0.9 + 0.099 * torch.rand(500, generator=g), "classic"
    if kind == "background":  # a sparse, faint cloud: the background shows between and through
        means, cov, _, opac = random_scene(60, g, spread=0.5, scale=0.03)
        return means, cov, torch.rand(60, 3, generator=g), 0.2 * opac, "classic"
    if kind == "antialiased":
        means, cov, _, opac = random_scene(400, g, spread=0.4, scale=0.01)  # small: the 2D filter matters
        return means, cov, torch.rand(400, 3, generator=g), opac, "antialiased"
    if kind == "empty":
        return torch.zeros(0, 3), torch.zeros(0, 3, 3), torch.zeros(0, 3), torch.zeros(0), "classic"
    if kind == "off_screen":  # beside, behind and in front of the camera's near plane
        means, cov, _, opac = random_scene(90, g, spread=0.05, scale=0.05)
        means[:30, 0] += 6.0
        means[30:60, 1] -= 4.0
        means[60:, 1] = -2.0 + 0.001  # closer than the near plane (0.01)
        return means, cov, torch.rand(90, 3, generator=g), opac, "classic"
    raise ValueError(kind)


KINDS = ["random", "anisotropic", "early_stop", "background", "antialiased", "empty", "off_screen"]


@pytest.mark.parametrize("kind", KINDS)
def test_warp_backend_matches_torch_backend(kind):
    """Both CPU backends apply the same rules in float32: image channels and alpha agree within 1/255 on every
    pixel. The scenes do what their name says (checked on the torch image): `early_stop` saturates pixels
    (alpha > 0.999), `background` leaves most of the image uncovered, `empty` and `off_screen` draw nothing
    but the background colour."""
    seed, g = fresh_seed()
    means, cov, cols, opac, mode = _scene(kind, g)
    cam = look_at((0.0, -2.0, 0.0), (0, 0, 0), (0, 0, 1), 40, 67, 53)
    bg = (0.9, 0.3, 0.1)
    ref = render(means, cov, cols, opac, cam, bg, "torch", mode)
    out = render(means, cov, cols, opac, cam, bg, "warp", mode)
    assert out.backend == "warp" and ref.backend == "torch"
    msg = f"seed {seed} {kind}"
    diff = (out.image - ref.image).abs().max().item()
    assert diff <= 1 / 255, f"{msg}: image differs by {diff:.2e}"
    assert (out.alpha - ref.alpha).abs().max().item() <= 1 / 255, msg
    covered = ref.alpha > 0.01
    if kind == "early_stop":
        assert (ref.alpha > 0.999).float().mean() > 0.05, msg
    if kind == "background":
        assert 0.05 < covered.float().mean() < 0.7, msg
    if kind in ("empty", "off_screen"):
        assert_close(out.image, torch.tensor(bg).expand(53, 67, 3), rtol=0, atol=0, msg=msg)
        assert not covered.any(), msg
    elif kind != "background":
        assert covered.float().mean() > 0.05, f"{msg}: the scene draws next to nothing"


def _stack(opacities: list[float], colors: list[tuple[float, float, float]], centre=(10.5, 10.5)):
    """A projection of Gaussians centred on one pixel centre, nearest first, each with conic I/4 (σ = 0 at the
    centre, so α there is the opacity), radius 6 px."""
    n = len(opacities)
    means2d = torch.tensor([centre] * n, dtype=torch.float32)
    conics = torch.tensor([[0.25, 0.0, 0.25]] * n)
    proj = Projection(
        means2d=means2d,
        conics=conics,
        depths=torch.arange(1.0, n + 1.0),
        radii=torch.full((n, 2), 6, dtype=torch.int32),
        opacities=torch.tensor(opacities),
        compensations=None,
        covars2d=torch.diag(torch.tensor([4.0, 4.0])).expand(n, 2, 2),
    )
    return proj, torch.tensor(colors)


def _composite_by_hand(opacities, colors, background):
    """The docstring's rule at one pixel, in float64: skip α < 1/255; stop, without drawing, once T(1 − α) ≤ 1e-4."""
    T, C = 1.0, [0.0, 0.0, 0.0]
    for a, c in zip(opacities, colors):
        a = min(a, 0.999)
        if a < 1 / 255:
            continue
        if T * (1 - a) <= 1e-4:
            break
        C = [C[k] + c[k] * a * T for k in range(3)]
        T *= 1 - a
    return [C[k] + T * background[k] for k in range(3)], 1 - T


@pytest.mark.parametrize("raster", [rasterize_warp, rasterize_tiles], ids=["warp", "torch"])
def test_exclusive_stop_and_alpha_threshold_at_a_pixel(raster):
    """At the pixel under a stack of Gaussians (α = opacity there): a Gaussian with α = 0.9/255 is skipped (it
    would darken and tint the pixel by ~0.35 %), one with α = 1.1/255 is drawn; red (α 0.99) leaves T = 0.01;
    green (α 0.995) would leave 5e-5 ≤ 1e-4, so compositing stops before green, which is NOT drawn (an inclusive
    stop adds ~0.01 of green, a missing stop also blue), and the background gets the remaining T = 0.01·(1 −
    1.1/255). α is capped at 0.999, so a lone opaque Gaussian (o = 1) is drawn with T = 0.001 left. Expected
    pixels come from the rule evaluated by hand in float64."""
    opac = [0.9 / 255, 1.1 / 255, 0.99, 0.995, 0.999]
    cols = [(1.0, 1.0, 1.0), (0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)]
    bg = (0.2, 0.4, 0.6)
    proj, colors = _stack(opac, cols)
    img, alpha = raster(proj, colors, 21, 21, torch.tensor(bg))
    want, want_alpha = _composite_by_hand(opac, cols, bg)
    assert want[1] == pytest.approx(0.4 * 0.01 * (1 - 1.1 / 255)), "the hand rule itself: green never drawn"
    assert_close(img[10, 10].double(), torch.tensor(want, dtype=torch.float64), rtol=0, atol=1e-6)
    assert_close(alpha[10, 10].item(), want_alpha, rtol=0, atol=1e-6)
    # a pixel 1 px right: σ = ½·0.25 = 0.125, every α shrinks by e^−0.125, green now leaves T > 1e-4 and draws
    shrink = math.exp(-0.125)
    want_right, _ = _composite_by_hand([o * shrink for o in opac], cols, bg)
    assert want_right[1] > 1e-3
    assert_close(img[10, 11].double(), torch.tensor(want_right, dtype=torch.float64), rtol=0, atol=1e-6)
    assert_close(img[0, 0], torch.tensor(bg), rtol=0, atol=0)  # outside every box: the background exactly
    # α is capped at 0.999: a fully opaque Gaussian leaves T = 0.001 > 1e-4 and is drawn (α = 1 would stop at once
    # and leave the background)
    proj, colors = _stack([1.0], [(1.0, 0.0, 0.0)])
    img, alpha = raster(proj, colors, 21, 21, torch.tensor(bg))
    want, want_alpha = _composite_by_hand([1.0], [(1.0, 0.0, 0.0)], bg)
    assert want_alpha == pytest.approx(0.999)
    assert_close(img[10, 10].double(), torch.tensor(want, dtype=torch.float64), rtol=0, atol=1e-6)


def test_warp_tile_lists_equal_torch_intersections():
    """The Warp tile lists (`raster_kernels.tile_lists`) hold exactly `_tile_intersections`' pairs: the same ids
    per tile in the same depth order, the same starts and counts, for tiles that do and do not divide the image,
    in float32 and float64."""
    seed, g = fresh_seed()
    means, cov, _, opac = random_scene(300, g, spread=0.6, scale=0.05)
    means[:20, 1] = -3.0  # behind the camera: not visible, in no list
    cam = look_at((0.0, -2.0, 0.2), (0, 0, 0), (0, 0, 1), 45, 75, 50)
    for dtype in (torch.float32, torch.float64):
        m, c, o = (t.to(dtype) for t in (means, cov, opac))
        proj = project_gaussians(m, c, cam.viewmat, cam.K, 75, 50, 0.3, 0.01, 1e10, "classic", o)
        for tile in (1, 3, 8, 16, 64):
            flat, starts, counts, _, _ = _tile_intersections(proj, 75, 50, tile)
            got = tile_lists(_depth_order(proj), proj.means2d, proj.radii, 75, 50, tile)
            assert flat.numel() > 100, f"seed {seed}: too few pairs"
            for name, a, b in zip(("flat", "starts", "counts"), (flat, starts, counts), got):
                assert torch.equal(a, b.long()), f"seed {seed} {dtype} tile {tile}: {name} differs"


def test_warp_pixels_do_not_depend_on_the_tile_size():
    """The tile only chooses which Gaussians a pixel visits, not how it composites them: with 4-, 8- (default) and
    16-px tiles the pixels agree within 1/255 (a larger tile may let a Gaussian reach just past the box outside
    which its α < 1/255, as in the torch backend); a wrong tile index or range moves whole blocks by far more."""
    seed, g = fresh_seed()
    means, cov, cols, opac, _ = _scene("random", g)
    cam = look_at((0.0, -2.0, 0.0), (0, 0, 0), (0, 0, 1), 40, 67, 53)
    proj = project_gaussians(means, cov, cam.viewmat, cam.K, 67, 53, 0.3, 0.01, 1e10, "classic", opac)
    bg = torch.tensor((0.9, 0.3, 0.1))
    img8, _ = rasterize_warp(proj, cols, 67, 53, bg, TILE_CPU)
    for tile in (4, 16):
        img, _ = rasterize_warp(proj, cols, 67, 53, bg, tile)
        assert (img - img8).abs().max().item() <= 1 / 255, f"seed {seed}: tile {tile}"
    assert (img8 != bg).any(dim=-1).float().mean() > 0.05, f"seed {seed}: the scene draws next to nothing"


def test_auto_picks_warp_on_the_cpu_unless_a_gradient_is_needed():
    """`auto` on CPU float32/float64 tensors without a gradient draws with Warp; with a tensor that requires a
    gradient (under autograd) or in float16 it draws with torch, and the gradient reaches the inputs;
    `torch` forces the torch backend; `warp` refuses a gradient and other dtypes in one sentence naming the fix.
    A config may name `render.backend = "warp"`; an unknown backend's message lists it."""
    cam = look_at((0, -2, 0), (0, 0, 0), (0, 0, 1), 40, 16, 16)
    means, cov, cols, opac = torch.zeros(1, 3), 0.01 * torch.eye(3)[None], torch.ones(1, 3), torch.ones(1)
    assert render(means, cov, cols, opac, cam).backend == "warp"
    assert render(means.double(), cov.double(), cols, opac, cam).backend == "warp"
    assert render(means, cov, cols, opac, cam, backend="torch").backend == "torch"
    assert render(means.half(), cov.half(), cols.half(), opac.half(), cam).backend == "torch"
    leaf = opac.clone().requires_grad_(True)
    out = render(means, cov, cols, leaf, cam)
    assert out.backend == "torch"
    out.image.sum().backward()
    assert leaf.grad is not None and leaf.grad.abs().sum() > 0
    with torch.no_grad():
        assert render(means, cov, cols, leaf, cam).backend == "warp"
    with pytest.raises(RenderError, match="no gradient; use backend='torch'"):
        render(means, cov, cols, leaf, cam, backend="warp")
    with pytest.raises(RenderError, match="float32 or float64 CPU tensors"):
        render(means.half(), cov.half(), cols.half(), opac.half(), cam, backend="warp")
    cfg = load_config(find_config("bread"))
    assert apply_overrides(cfg, keys={"render.backend": "warp"}).render.backend == "warp"
    with pytest.raises(ConfigError, match="auto, gsplat, torch, warp"):
        apply_overrides(cfg, keys={"render.backend": "vulkan"})


def test_info_warm_up_loads_the_rasterizer_on_the_cpu_only():
    """`fracture-gs info --warm-up` puts every module a run launches into the kernel cache: on the CPU that includes
    the Warp rasterizer's (else a fresh machine's first CPU run compiles it), on CUDA it does not (gsplat draws
    there, so compiling it would be wasted)."""
    from fracture_gs.cli.warm_up import kernel_modules

    assert "fracture_gs.render.raster_kernels" in [m.name for m in kernel_modules("cpu")]
    assert "fracture_gs.render.raster_kernels" not in [m.name for m in kernel_modules("cuda:0")]


@pytest.mark.slow
def test_raster_cpu_benchmark_runs_and_compares_the_backends(tmp_path):
    """benchmarks/raster_cpu.py, as a user runs it (small): a row per set, backend and Warp part with positive
    times, and the two backends' images within 1/255 of each other on both sets."""
    import os
    import re
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    args = [sys.executable, str(root / "benchmarks" / "raster_cpu.py"), "--repeats", "2", "--particles", "2000"]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")])}  # this checkout
    proc = subprocess.run(
        args + ["--resolution", "96x64"], capture_output=True, text=True, timeout=600, cwd=tmp_path, env=env
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    rows = [line.split("|")[1:-1] for line in proc.stdout.splitlines() if re.match(r"\| (drawn|all) \|", line)]
    assert [r[2].strip() for r in rows[:2]] == ["torch", "warp"] and len(rows) == 10, proc.stdout
    assert all(float(r[3]) > 0 and float(r[5]) >= 0 for r in rows), proc.stdout
    diffs = [float(m) for m in re.findall(r"torch − warp\| over pixels and channels: ([0-9.e+-]+)", proc.stdout)]
    assert len(diffs) == 2 and max(diffs) <= 1 / 255, proc.stdout
