"""Front-to-back compositing of depth-sorted Gaussians in Warp kernels on the CPU: the "warp" backend of
`splat.render` (DESIGN.md "Rendering").

`tile_lists` builds `splat._tile_intersections`' lists (Gaussian ids sorted by (tile, depth), a [start, start +
count) range per tile) in three launches. `composite` then runs one thread per pixel (x, y), which walks its tile's
list with the rules of `splat`'s module docstring, in the operation order of the torch rasterizer's
`_composite_chunk`:

    u, v = x + ½ − μ_x, y + ½ − μ_y,   ln α = ln o − ½a u² − ½c v² − b u v,   α = min(0.999, e^{ln α})
    α < 1/255: skipped;   T(1 − α) ≤ 1e-4: stop before this Gaussian (exclusive);   else C += c α T, T ← T(1 − α)
    image = C + T·background,   alpha = 1 − T

The tile only chooses which Gaussians a pixel visits; a pixel's arithmetic is its own, in the inputs' dtype
(float32 or float64, one overload each). Warp compiles CPU kernels to C++ and runs a launch on one thread; bread's
320×240 frame takes ~14 ms here against ~43 ms for the torch rasterizer on one thread
(`benchmarks/raster_cpu.py`). Forward only: gradients take the torch path.
"""

from __future__ import annotations

import math
from typing import Any

import torch
import warp as wp

from ..runtime import ensure_warp

wp.set_module_options({"enable_backward": False})

ALPHA_THRESHOLD = wp.constant(1.0 / 255.0)  # as splat.ALPHA_THRESHOLD, T_THRESHOLD, ALPHA_MAX
T_THRESHOLD = wp.constant(1e-4)
ALPHA_MAX = wp.constant(0.999)
LN_ALPHA_SKIP = wp.constant(math.log(1.0 / 255.0) - 1e-3)
"""Below this ln α, α < 1/255 for certain (e^{−0.001} ≈ 1 − 1e-3, far beyond exp's rounding): the pair is
skipped without evaluating exp; between it and ln(1/255) the exact test on α decides, as in the torch path."""
COLUMNS = 9  # per-Gaussian row of `composite_pixels`: μ_x, μ_y, a, b, c, ln o, r, g, b


@wp.kernel
def tile_boxes(
    order: wp.array(dtype=wp.int64),  # [V] visible Gaussians in depth order
    means2d: wp.array2d(dtype=Any),  # [N, 2] pixel coordinates
    radii: wp.array2d(dtype=wp.int32),  # [N, 2] screen half-extents [px]
    tile: int,
    tiles_w: int,
    tiles_h: int,
    boxes: wp.array2d(dtype=wp.int32),  # [V, 4] out: tile x0, x1, y0, y1 (half-open)
):
    """The tiles a Gaussian's box μ ± r touches, with `splat._tile_intersections`' arithmetic (floor/ceil of
    (μ ± r)/tile in the means' dtype, clamped to the grid)."""
    j = wp.tid()
    i = int(order[j])
    size = means2d.dtype(tile)
    mx = means2d[i, 0] / size
    my = means2d[i, 1] / size
    rx = means2d.dtype(radii[i, 0]) / size
    ry = means2d.dtype(radii[i, 1]) / size
    boxes[j, 0] = wp.clamp(int(wp.floor(mx - rx)), 0, tiles_w)
    boxes[j, 1] = wp.clamp(int(wp.ceil(mx + rx)), 0, tiles_w)
    boxes[j, 2] = wp.clamp(int(wp.floor(my - ry)), 0, tiles_h)
    boxes[j, 3] = wp.clamp(int(wp.ceil(my + ry)), 0, tiles_h)


@wp.kernel
def count_tiles(boxes: wp.array2d(dtype=wp.int32), tiles_w: int, counts: wp.array(dtype=wp.int32)):
    """Thread = a row of tiles: how many boxes touch each of its tiles (`counts` zeroed before)."""
    ty = wp.tid()
    for j in range(boxes.shape[0]):
        if boxes[j, 2] <= ty and ty < boxes[j, 3]:
            for tx in range(boxes[j, 0], boxes[j, 1]):
                counts[ty * tiles_w + tx] += 1


@wp.kernel
def fill_tiles(
    order: wp.array(dtype=wp.int64),  # [V] visible Gaussians in depth order
    boxes: wp.array2d(dtype=wp.int32),  # [V, 4]
    tiles_w: int,
    cursor: wp.array(dtype=wp.int32),  # [tiles] each tile's start on entry, its end on exit
    flat: wp.array(dtype=wp.int32),  # [M] out: Gaussian ids by (tile, depth)
):
    """Thread = a row of tiles: appends each Gaussian, in depth order, to the list of every tile of the row
    its box touches. A row's tiles belong to its thread alone, so the lists come out the same however the
    threads run."""
    ty = wp.tid()
    for j in range(boxes.shape[0]):
        if boxes[j, 2] <= ty and ty < boxes[j, 3]:
            for tx in range(boxes[j, 0], boxes[j, 1]):
                t = ty * tiles_w + tx
                flat[cursor[t]] = wp.int32(order[j])
                cursor[t] += 1


@wp.kernel
def composite_pixels(
    flat: wp.array(dtype=wp.int32),  # [M] Gaussian ids sorted by (tile, depth)
    starts: wp.array(dtype=wp.int32),  # [tiles] first entry of each tile in `flat`
    counts: wp.array(dtype=wp.int32),  # [tiles] entries of each tile
    gauss: wp.array2d(dtype=Any),  # [N, COLUMNS]: μ (pixels), conic (a, b, c) of Σ₂⁻¹, ln o, colour
    background: wp.array(dtype=Any),  # [3]
    tile: int,
    tiles_w: int,
    image: wp.array3d(dtype=Any),  # [H, W, 3] out
    alpha: wp.array2d(dtype=Any),  # [H, W] out
):
    y, x = wp.tid()
    zero = gauss.dtype(0.0)
    half = gauss.dtype(0.5)
    one = gauss.dtype(1.0)
    px = gauss.dtype(x) + half  # pixel centre
    py = gauss.dtype(y) + half
    t = (y // tile) * tiles_w + x // tile
    start = starts[t]
    T = one
    r = zero
    g = zero
    b = zero
    for k in range(start, start + counts[t]):
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
            break  # exclusive: this Gaussian is not drawn
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
    wp.overload(tile_boxes, {"means2d": wp.array2d(dtype=_dt)})
    wp.overload(
        composite_pixels,
        {
            "gauss": wp.array2d(dtype=_dt),
            "background": wp.array(dtype=_dt),
            "image": wp.array3d(dtype=_dt),
            "alpha": wp.array2d(dtype=_dt),
        },
    )


def _launch(kernel, dim, inputs: list) -> None:
    wp.launch(
        kernel, dim=dim, inputs=[wp.from_torch(a) if isinstance(a, torch.Tensor) else a for a in inputs], device="cpu"
    )


def tile_lists(
    order: torch.Tensor,  # [V] int64 visible Gaussians in depth order (ties by index)
    means2d: torch.Tensor,  # [N, 2]
    radii: torch.Tensor,  # [N, 2] int32
    width: int,
    height: int,
    tile: int,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:  # [M], [tiles], [tiles] int32
    """`splat._tile_intersections`' lists (flat ids by (tile, depth), starts, counts) in three launches:
    boxes, a count per tile, then each tile row filled in depth order; int32."""
    ensure_warp()
    tiles_w, tiles_h = (width + tile - 1) // tile, (height + tile - 1) // tile
    counts = torch.zeros(tiles_w * tiles_h, dtype=torch.int32)
    if order.numel() == 0:
        return torch.zeros(0, dtype=torch.int32), counts.clone(), counts
    order = order.to(torch.int64).contiguous()
    boxes = torch.empty(order.numel(), 4, dtype=torch.int32)
    _launch(
        tile_boxes,
        order.numel(),
        [order, means2d.detach().contiguous(), radii.to(torch.int32).contiguous(), tile, tiles_w, tiles_h, boxes],
    )
    _launch(count_tiles, tiles_h, [boxes, tiles_w, counts])
    ends = torch.cumsum(counts, 0, dtype=torch.int32)
    starts = ends - counts
    flat = torch.empty(int(ends[-1]), dtype=torch.int32)
    _launch(fill_tiles, tiles_h, [order, boxes, tiles_w, starts.clone(), flat])
    return flat, starts, counts


def composite(
    flat: torch.Tensor,  # [M] int32 Gaussian ids sorted by (tile, depth)
    starts: torch.Tensor,  # [tiles] int32
    counts: torch.Tensor,  # [tiles] int32
    means2d: torch.Tensor,  # [N, 2]
    conics: torch.Tensor,  # [N, 3]
    opacities: torch.Tensor,  # [N]
    colors: torch.Tensor,  # [N, 3]
    background: torch.Tensor,  # [3]
    width: int,
    height: int,
    tile: int,
) -> tuple[torch.Tensor, torch.Tensor]:  # [H, W, 3], [H, W]
    """The image and alpha of the tile lists, in means2d's dtype (float32 or float64), on the CPU."""
    ensure_warp()
    dt = means2d.dtype
    image = torch.empty(height, width, 3, dtype=dt)
    alpha = torch.empty(height, width, dtype=dt)
    if flat.numel() == 0:  # nothing to visit: a one-entry list no tile points into keeps the arrays non-empty
        flat = torch.zeros(1, dtype=torch.int32)
    # one row per Gaussian, so a pixel's visit reads one cache line; ln 0 = −inf: α = 0, skipped
    log_opac = torch.log(opacities.detach().to(dt))[:, None]
    gauss = torch.cat([means2d.detach(), conics.detach().to(dt), log_opac, colors.detach().to(dt)], dim=1)  # [N, 9]
    if gauss.shape[0] == 0:  # no Gaussians (every count is 0): one placeholder row, never read
        gauss = gauss.new_zeros(1, COLUMNS)
    lists = [a.to(torch.int32).contiguous() for a in (flat, starts, counts)]
    tiles_w = (width + tile - 1) // tile
    _launch(
        composite_pixels,
        (height, width),
        [*lists, gauss, background.detach().to(dt).contiguous(), tile, tiles_w, image, alpha],
    )
    return image, alpha
