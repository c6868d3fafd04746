"""The Warp rasterizer's tile thread (`raster_kernels.composite_tiles`) against the straightforward thread per pixel,
bit for bit: the tile thread changes the loop order and skips pixels whose ln α is below the skip threshold for
certain (`span_reach`), so every pixel must come out with exactly the bits of a per-pixel walk of its tile's list,
in float32 and float64, on adversarial inputs: ln α within rounding of the threshold at many pixel centres, far and
steep Gaussians (large terms), needles (nearly singular conics), conics that are not positive definite, non-finite
values, opaque stacks (early stops), empty lists and tiles that do not divide the image."""

from __future__ import annotations

import math
from typing import Any

import pytest
import torch
import warp as wp
from test_render import fresh_seed

from fracture_gs.render.raster_kernels import (
    ALPHA_MAX,
    ALPHA_THRESHOLD,
    LN_ALPHA_SKIP,
    T_THRESHOLD,
    composite,
    gauss_rows,
)
from fracture_gs.runtime import ensure_warp

wp.set_module_options({"enable_backward": False})


@wp.kernel
def composite_pixels(
    flat: wp.array(dtype=wp.int32),  # [M] Gaussian ids sorted by (tile, depth)
    starts: wp.array(dtype=wp.int32),  # [tiles]
    counts: wp.array(dtype=wp.int32),  # [tiles]
    gauss: wp.array2d(dtype=Any),  # [N, COLUMNS] `gauss_rows`
    background: wp.array(dtype=Any),  # [3]
    tile: int,
    tiles_w: int,
    image: wp.array3d(dtype=Any),  # [H, W, 3] out
    alpha: wp.array2d(dtype=Any),  # [H, W] out
):
    """Thread = a pixel: walks its tile's whole list, the rules of `raster_kernels`' docstring written out, with its
    constants (Warp makes them float32 literals, so a float64 kernel compares with their float32 values)."""
    y, x = wp.tid()
    zero = gauss.dtype(0.0)
    half = gauss.dtype(0.5)
    one = gauss.dtype(1.0)
    px = gauss.dtype(x) + half
    py = gauss.dtype(y) + half
    t = (y // tile) * tiles_w + x // tile
    T = one
    r = zero
    g = zero
    b = zero
    for k in range(starts[t], starts[t] + counts[t]):
        i = flat[k]
        u = px - gauss[i, 0]
        v = py - gauss[i, 1]
        ln_a = gauss[i, 5] - half * gauss[i, 2] * u * u - half * gauss[i, 4] * v * v - gauss[i, 3] * u * v
        if ln_a < gauss.dtype(LN_ALPHA_SKIP):
            continue
        a = wp.min(wp.exp(ln_a), gauss.dtype(ALPHA_MAX))
        if a < gauss.dtype(ALPHA_THRESHOLD):
            continue
        next_T = T * (one - a)
        if next_T <= gauss.dtype(T_THRESHOLD):
            break
        w = a * T
        r += gauss[i, 6] * w
        g += gauss[i, 7] * w
        b += gauss[i, 8] * w
        T = next_T
    image[y, x, 0] = r + T * background[0]
    image[y, x, 1] = g + T * background[1]
    image[y, x, 2] = b + T * background[2]
    alpha[y, x] = one - T


for _dt in (wp.float32, wp.float64):
    wp.overload(
        composite_pixels,
        {
            "gauss": wp.array2d(dtype=_dt),
            "background": wp.array(dtype=_dt),
            "image": wp.array3d(dtype=_dt),
            "alpha": wp.array2d(dtype=_dt),
        },
    )


def _per_pixel(flat, starts, counts, means2d, conics, opacities, colors, background, width, height, tile):
    """`composite`'s image and alpha from a thread per pixel."""
    ensure_warp()
    dt = means2d.dtype
    image, alpha = torch.empty(height, width, 3, dtype=dt), torch.empty(height, width, dtype=dt)
    flat = flat if flat.numel() else flat.new_zeros(1)  # a non-empty array no tile points into
    lists = [wp.from_torch(a.to(torch.int32).contiguous()) for a in (flat, starts, counts)]
    gauss = wp.from_torch(gauss_rows(means2d, conics, opacities, colors))
    args = [gauss, wp.from_torch(background.to(dt).contiguous()), tile, (width + tile - 1) // tile]
    wp.launch(
        composite_pixels, (height, width), [*lists, *args, wp.from_torch(image), wp.from_torch(alpha)], device="cpu"
    )
    return image, alpha


def _lists(n: int, width: int, height: int, tile: int, g, per_tile: int = 12):
    """Random tile lists over n Gaussians: each tile visits `per_tile` ids on average (repeats allowed), some
    tiles none."""
    tiles = ((width + tile - 1) // tile) * ((height + tile - 1) // tile)
    counts = torch.randint(0, 2 * per_tile + 1, (tiles,), generator=g)
    counts[torch.rand(tiles, generator=g) < 0.2] = 0
    flat = torch.randint(0, n, (int(counts.sum()),), generator=g)
    return flat, torch.cumsum(counts, 0) - counts, counts


def _threshold_scene(n: int, width: int, height: int, g, dtype):
    """Gaussians whose ln α at many pixel centres lies within a few ulp of LN_ALPHA_SKIP or of ln(1/255) (where α
    decides whether the pixel draws): centres on pixel centres or half-way between, conics with small rational
    entries (so ½a u² + ½c v² + b u v is exact at those pixels), ln o = the threshold + that value, then nudged by a
    few ulp either way."""
    means2d = torch.stack(
        [torch.randint(0, width, (n,), generator=g), torch.randint(0, height, (n,), generator=g)], 1
    ).to(dtype) + 0.5 * torch.randint(0, 2, (n, 2), generator=g).to(dtype)
    a = torch.randint(1, 9, (n,), generator=g).to(dtype) / 8
    c = torch.randint(1, 9, (n,), generator=g).to(dtype) / 8
    b = (torch.randint(-3, 4, (n,), generator=g).to(dtype) / 8) * torch.sqrt(a * c)  # |b| < sqrt(ac)
    b = torch.round(b * 64) / 64
    du = torch.randint(-4, 5, (n,), generator=g).to(dtype)
    dv = torch.randint(-4, 5, (n,), generator=g).to(dtype)
    sigma = 0.5 * a * du * du + 0.5 * c * dv * dv + b * du * dv
    eps = torch.finfo(dtype).eps
    pick = torch.rand(n, generator=g) < 0.5
    threshold = torch.where(
        pick, torch.tensor(LN_ALPHA_SKIP, dtype=dtype), torch.tensor(math.log(1 / 255), dtype=dtype)
    )
    ln_o = (threshold + sigma) * (1 + eps * torch.randint(-4, 5, (n,), generator=g).to(dtype))
    opac = torch.exp(ln_o).clamp_max(1.0)
    return means2d, torch.stack([a, b, c], 1), opac


def _wild_scene(n: int, width: int, height: int, g, dtype):
    """Random Gaussians of every kind: small and large, far off the image, needles (det ≈ 0), conics that are not
    positive definite or not finite, opacities from 0 to 1 (some nearly opaque: early stops)."""
    means2d = (torch.rand(n, 2, generator=g, dtype=torch.float64) * 1.6 - 0.3) * torch.tensor([width, height])
    scale = 10 ** (torch.rand(n, generator=g, dtype=torch.float64) * 6 - 4)  # conic scale 1e-4 … 1e2
    a = scale * (0.2 + torch.rand(n, generator=g, dtype=torch.float64))
    c = scale * (0.2 + torch.rand(n, generator=g, dtype=torch.float64))
    rho = torch.rand(n, generator=g, dtype=torch.float64) * 2 - 1
    rho[: n // 4] = torch.sign(rho[: n // 4]) * (1 - 10 ** -(3 + 5 * torch.rand(n // 4, generator=g)))  # needles
    b = rho * torch.sqrt(a * c)
    conics = torch.stack([a, b, c], 1)
    k = n // 20
    conics[k : 2 * k, 1] = 2 * torch.sqrt(a * c)[k : 2 * k]  # det < 0
    conics[2 * k : 3 * k, 0] = -conics[2 * k : 3 * k, 0]  # a < 0
    conics[3 * k, 0], conics[3 * k + 1, 1], conics[3 * k + 2, 2] = math.inf, math.nan, -math.inf
    means2d[3 * k + 3, 0] = math.nan
    opac = torch.rand(n, generator=g, dtype=torch.float64)
    opac[4 * k : 6 * k] = 0.99 + 0.01 * opac[4 * k : 6 * k]
    opac[6 * k] = 0.0
    return means2d.to(dtype), conics.to(dtype), opac.to(dtype)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("scene", ["threshold", "wild"])
@pytest.mark.parametrize(("tile", "width", "height"), [(8, 61, 45), (8, 64, 48), (3, 20, 17), (16, 70, 33), (1, 9, 7)])
def test_tile_thread_equals_pixel_thread_bit_for_bit(dtype, scene, tile, width, height):
    """The tile thread and the thread per pixel give the same image and alpha bits on the same lists."""
    seed, g = fresh_seed()
    n = 400
    make = _threshold_scene if scene == "threshold" else _wild_scene
    means2d, conics, opac = make(n, width, height, g, dtype)
    cols = torch.rand(n, 3, generator=g).to(dtype)
    bg = torch.tensor([0.2, 0.5, 0.9], dtype=dtype)
    flat, starts, counts = _lists(n, width, height, tile, g)
    args = (flat, starts, counts, means2d, conics, opac, cols, bg, width, height, tile)
    want_img, want_alpha = _per_pixel(*args)
    img, alpha = composite(*args)
    msg = f"seed {seed} {scene} {dtype} tile {tile}"
    assert torch.equal(img.view(-1).view(torch.uint8), want_img.view(-1).view(torch.uint8)), msg
    assert torch.equal(alpha.view(-1).view(torch.uint8), want_alpha.view(-1).view(torch.uint8)), msg
    if scene == "threshold":  # the scene does what it says: pixels on both sides of the threshold
        u = torch.arange(width, dtype=dtype)[None, :] + 0.5 - means2d[:, :1]  # [N, W]
        v = torch.arange(height, dtype=dtype)[None, :] + 0.5 - means2d[:, 1:]  # [N, H]
        a, b, c = (conics[:, k, None, None] for k in range(3))
        ln = torch.log(opac)[:, None, None] - 0.5 * a * u[:, None, :] ** 2 - 0.5 * c * v[:, :, None] ** 2
        ln = ln - b * u[:, None, :] * v[:, :, None]
        for threshold in (LN_ALPHA_SKIP, math.log(1 / 255)):
            near = (ln - threshold).abs() <= 2048 * torch.finfo(dtype).eps
            assert near.sum() > 50 and (ln[near] < threshold).any() and (ln[near] >= threshold).any(), msg


def test_tile_thread_on_empty_lists():
    """No Gaussian at all, and lists that visit nothing: the background everywhere, alpha 0."""
    for n in (0, 5):
        means2d, conics = torch.zeros(n, 2), torch.tensor([[1.0, 0.0, 1.0]]).expand(n, 3)
        tiles = 4 * 3
        counts = torch.zeros(tiles, dtype=torch.int32)
        args = (torch.zeros(0, dtype=torch.int32), counts, counts, means2d, conics, torch.ones(n), torch.ones(n, 3))
        img, alpha = composite(*args, torch.tensor([0.1, 0.2, 0.3]), 30, 20, 8)
        assert torch.equal(img, torch.tensor([0.1, 0.2, 0.3]).expand(20, 30, 3)) and not alpha.any()
