"""Front-to-back compositing of depth-sorted Gaussians in Warp kernels on the CPU: the "warp" backend of
`splat.render` (DESIGN.md "Rendering").

`tile_lists` builds `splat._tile_intersections`' lists (Gaussian ids sorted by (tile, depth), a [start, start +
count) range per tile) in three launches. `composite` then runs one thread per tile, in which every pixel (x, y)
walks its tile's list with the rules of `splat`'s module docstring, in the operation order of the torch
rasterizer's `_composite_chunk`:

    u, v = x + ½ − μ_x, y + ½ − μ_y,   ln α = ln o − ½a u² − ½c v² − b u v,   α = min(0.999, e^{ln α})
    α < 1/255: skipped;   T(1 − α) ≤ 1e-4: stop before this Gaussian (exclusive);   else C += c α T, T ← T(1 − α)
    image = C + T·background,   alpha = 1 − T

The tile only chooses which Gaussians a pixel visits; a pixel's arithmetic is its own, in the inputs' dtype
(float32 or float64, one overload each), the same as a thread per pixel would compute (`tests/test_raster_tiles.py`
holds that kernel and compares them bit for bit); the tile thread only skips the pixels that, for certain, would skip
the Gaussian. Warp compiles CPU kernels to C++ and runs a launch on one thread; bread's 320×240 frame takes ~7 ms
here (~12 ms with a thread per pixel) against ~43 ms for the torch rasterizer on one thread
(`benchmarks/raster_cpu.py`). Forward only: gradients take the torch path.

`deform` gives the frame's covariances Σ = F Σ⁰ Fᵀ (`gaussians.deform_covariances` on the CPU) with the bits of its
torch expression, a few times faster than torch's batched 3×3 products.
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
SPAN_MARGIN_REL = 1e-5  # `row_span`'s margin on ln α: ×S (float32 rounds ln α by ≤ 8·2⁻²⁴·S ≈ 5e-7·S) ...
SPAN_MARGIN_ABS = 1e-4  # ... plus this, for underflowing terms
COLUMNS = 9  # per-Gaussian row of `composite_tiles`: μ_x, μ_y, a, b, c, ln o, r, g, b


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
    """One thread: how many boxes touch each tile (`counts` zeroed before), each box counted at its tiles only."""
    for j in range(boxes.shape[0]):
        for ty in range(boxes[j, 2], boxes[j, 3]):
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
    """One thread: appends each Gaussian, in depth order, to the list of every tile its box touches, so each list
    comes out in depth order."""
    for j in range(boxes.shape[0]):
        i = wp.int32(order[j])
        for ty in range(boxes[j, 2], boxes[j, 3]):
            for tx in range(boxes[j, 0], boxes[j, 1]):
                t = ty * tiles_w + tx
                flat[cursor[t]] = i
                cursor[t] += 1


@wp.func
def span_reach(
    x0: int,
    x1: int,
    y0: int,
    y1: int,
    mx: wp.float64,
    my: wp.float64,
    a: wp.float64,
    b: wp.float64,
    c: wp.float64,
    ln_o: wp.float64,
    skip: wp.float64,
):
    """d0 = 2a(ln o − skip + E) of a Gaussian over the tile [x0, x1) × [y0, y1): with u = x + ½ − μ_x, v = y + ½ −
    μ_y and f = ln o − ½a u² − ½c v² − b u v the exact ln α of pixel (x, y), f ≥ skip − E is (a u + b v)² ≤ d0 −
    det v², det = ac − b² (for a > 0). E = SPAN_MARGIN_REL·S + SPAN_MARGIN_ABS, S = |ln o| + ½a u² + ½c v² +
    |b u v| at the tile's largest |u| and |v|, is far above the ≤ 8 ulp·S by which a pixel's rounded ln α can
    exceed f, and the ≈ 1e-15·S by which this float64 arithmetic can err: a pixel with (a u + b v)² > d0 − det v²
    has a rounded ln α below skip for certain."""
    half = wp.float64(0.5)
    um = wp.max(wp.abs(wp.float64(x0) + half - mx), wp.abs(wp.float64(x1) - half - mx))
    vm = wp.max(wp.abs(wp.float64(y0) + half - my), wp.abs(wp.float64(y1) - half - my))
    s = wp.abs(ln_o) + half * a * um * um + half * c * vm * vm + wp.abs(b) * um * vm
    e = wp.float64(SPAN_MARGIN_REL) * s + wp.float64(SPAN_MARGIN_ABS)
    return wp.float64(2.0) * a * (ln_o - skip + e)


@wp.kernel
def composite_tiles(
    flat: wp.array(dtype=wp.int32),  # [M] Gaussian ids sorted by (tile, depth)
    starts: wp.array(dtype=wp.int32),  # [tiles] first entry of each tile in `flat`
    counts: wp.array(dtype=wp.int32),  # [tiles] entries of each tile
    gauss: wp.array2d(dtype=Any),  # [N, COLUMNS]: μ (pixels), conic (a, b, c) of Σ₂⁻¹, ln o, colour
    background: wp.array(dtype=Any),  # [3]
    tile: int,
    tiles_w: int,
    image: wp.array3d(dtype=Any),  # [H, W, 3] out; each pixel's colour sum C while compositing
    alpha: wp.array2d(dtype=Any),  # [H, W] out; each pixel's T while compositing, −T once it stopped
):
    """Thread = a tile: every pixel of the tile walks the tile's list with the module docstring's rules. The
    Gaussian is the outer loop, so its row is read once per tile and its terms of ln α that depend on the pixel's
    row only (v, ½c v²) once per row; each pixel's ln α, α, T and C take the very operations, in the same order,
    of a per-pixel walk. Pixels whose ln α is below LN_ALPHA_SKIP for certain are not evaluated (`span_reach`:
    per row, the u between (−b v ± sqrt(d0 − det v²))/a, widened to whole pixels), and the tile's list ends early
    once all its pixels have stopped."""
    t = wp.tid()
    zero = gauss.dtype(0.0)
    half = gauss.dtype(0.5)
    one = gauss.dtype(1.0)
    f64_half = wp.float64(0.5)
    f64_zero = wp.float64(0.0)
    skip = wp.float64(gauss.dtype(LN_ALPHA_SKIP))  # the threshold as the pixels compare with it
    x0 = (t % tiles_w) * tile
    y0 = (t // tiles_w) * tile
    x1 = wp.min(x0 + tile, alpha.shape[1])
    y1 = wp.min(y0 + tile, alpha.shape[0])
    for y in range(y0, y1):
        for x in range(x0, x1):
            alpha[y, x] = one
            image[y, x, 0] = zero
            image[y, x, 1] = zero
            image[y, x, 2] = zero
    live = (x1 - x0) * (y1 - y0)  # pixels not stopped yet
    start = starts[t]
    for k in range(start, start + counts[t]):
        i = flat[k]
        mx = gauss[i, 0]
        my = gauss[i, 1]
        ha = half * gauss[i, 2]
        hc = half * gauss[i, 4]
        cb = gauss[i, 3]
        ln_o = gauss[i, 5]
        # the spans, in float64, where every input is finite and the conic positive definite; else every pixel
        a64 = wp.float64(gauss[i, 2])
        b64 = wp.float64(cb)
        c64 = wp.float64(gauss[i, 4])
        mx64 = wp.float64(mx)
        my64 = wp.float64(my)
        det = a64 * c64 - b64 * b64
        finite = wp.isfinite(det) and wp.isfinite(wp.float64(ln_o)) and wp.isfinite(mx64) and wp.isfinite(my64)
        spans = finite and a64 > f64_zero and det > f64_zero
        d0 = f64_zero
        inv_a = f64_zero
        if spans:
            d0 = span_reach(x0, x1, y0, y1, mx64, my64, a64, b64, c64, wp.float64(ln_o), skip)
            inv_a = wp.float64(1.0) / a64
            if d0 < f64_zero:
                continue  # no pixel of the tile reaches the threshold
        for y in range(y0, y1):
            xa = x0
            xb = x1
            if spans:
                v64 = wp.float64(y) + f64_half - my64
                disc = d0 - det * v64 * v64
                if disc < f64_zero:
                    continue  # no pixel of the row
                hw = wp.sqrt(disc) * inv_a
                centre = mx64 - f64_half - b64 * v64 * inv_a  # u = 0 at x = μ_x − ½
                # clamped to [x0, x1] ⊂ [0, W], truncation is floor: one pixel more than the span at most
                xa = int(wp.clamp(centre - hw, wp.float64(x0), wp.float64(x1)))
                xb = int(wp.clamp(centre + hw + wp.float64(1.0), wp.float64(x0), wp.float64(x1)))
            v = (gauss.dtype(y) + half) - my  # pixel centre y − μ_y
            cv = hc * v * v
            for x in range(xa, xb):
                T = alpha[y, x]
                if T < zero:
                    continue  # stopped
                u = (gauss.dtype(x) + half) - mx
                ln_a = ln_o - ha * u * u - cv - cb * u * v
                if ln_a < gauss.dtype(LN_ALPHA_SKIP):
                    continue
                a = wp.min(wp.exp(ln_a), gauss.dtype(ALPHA_MAX))
                if a < gauss.dtype(ALPHA_THRESHOLD):
                    continue
                next_T = T * (one - a)
                if next_T <= gauss.dtype(T_THRESHOLD):
                    alpha[y, x] = -T  # exclusive: this Gaussian is not drawn, and the pixel stops
                    live -= 1
                    continue
                w = a * T
                image[y, x, 0] = image[y, x, 0] + gauss[i, 6] * w
                image[y, x, 1] = image[y, x, 1] + gauss[i, 7] * w
                image[y, x, 2] = image[y, x, 2] + gauss[i, 8] * w
                alpha[y, x] = next_T
        if live == 0:
            break
    for y in range(y0, y1):
        for x in range(x0, x1):
            T = wp.abs(alpha[y, x])
            image[y, x, 0] = image[y, x, 0] + T * background[0]
            image[y, x, 1] = image[y, x, 1] + T * background[1]
            image[y, x, 2] = image[y, x, 2] + T * background[2]
            alpha[y, x] = one - T


for _dt in (wp.float32, wp.float64):
    wp.overload(tile_boxes, {"means2d": wp.array2d(dtype=_dt)})
    wp.overload(
        composite_tiles,
        {
            "gauss": wp.array2d(dtype=_dt),
            "background": wp.array(dtype=_dt),
            "image": wp.array3d(dtype=_dt),
            "alpha": wp.array2d(dtype=_dt),
        },
    )


@wp.func
def _dot3(a0: Any, a1: Any, a2: Any, b0: Any, b1: Any, b2: Any):
    """((0 + a0 b0) + a1 b1) + a2 b2: one entry of a 3×3 product as torch's CPU bmm sums it for small matrices
    (from +0, k in order), so the same bits, signed zeros included."""
    return ((type(a0)(0.0) + a0 * b0) + a1 * b1) + a2 * b2


@wp.kernel
def _deform_kernel(
    F: wp.array(dtype=Any),  # [N] 3×3
    cov0: wp.array(dtype=Any),  # [N] 3×3
    out: wp.array(dtype=Any),  # [N] 3×3 out: ½(S + Sᵀ), S = (F Σ⁰) Fᵀ
):
    """`gaussians.deform_covariances`' torch expression per Gaussian, with its operations in its order: M = F Σ⁰
    and S = M Fᵀ as `_dot3` sums, then ½(S + Sᵀ)."""
    n = wp.tid()
    f = F[n]
    c = cov0[n]
    m = out.dtype()
    for i in range(3):
        for j in range(3):
            m[i, j] = _dot3(f[i, 0], f[i, 1], f[i, 2], c[0, j], c[1, j], c[2, j])
    s = out.dtype()
    for i in range(3):
        for j in range(3):
            s[i, j] = _dot3(m[i, 0], m[i, 1], m[i, 2], f[j, 0], f[j, 1], f[j, 2])
    r = out.dtype()
    for i in range(3):
        for j in range(3):
            r[i, j] = type(s[i, j])(0.5) * (s[i, j] + s[j, i])
    out[n] = r


for _mat in (wp.mat33f, wp.mat33d):
    wp.overload(_deform_kernel, {"F": wp.array(dtype=_mat), "cov0": wp.array(dtype=_mat), "out": wp.array(dtype=_mat)})


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
    boxes, a count per tile, then the lists filled in depth order (one thread each: a box visits only its own
    tiles); int32."""
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
    _launch(count_tiles, 1, [boxes, tiles_w, counts])
    ends = torch.cumsum(counts, 0, dtype=torch.int32)
    starts = ends - counts
    flat = torch.empty(int(ends[-1]), dtype=torch.int32)
    _launch(fill_tiles, 1, [order, boxes, tiles_w, starts.clone(), flat])
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
    lists = [a.to(torch.int32).contiguous() for a in (flat, starts, counts)]
    tiles_w = (width + tile - 1) // tile
    _launch(
        composite_tiles,
        tiles_w * ((height + tile - 1) // tile),
        [*lists, gauss_rows(means2d, conics, opacities, colors), background.detach().to(dt).contiguous(), tile]
        + [tiles_w, image, alpha],
    )
    return image, alpha


def gauss_rows(
    means2d: torch.Tensor,  # [N, 2]
    conics: torch.Tensor,  # [N, 3]
    opacities: torch.Tensor,  # [N]
    colors: torch.Tensor,  # [N, 3]
) -> torch.Tensor:  # [max(N, 1), COLUMNS] in means2d's dtype
    """The compositing kernel's per-Gaussian rows (μ, conic, ln o, colour): one row per Gaussian, so a visit reads
    one cache line; ln 0 = −inf (α = 0, skipped). No Gaussians: one placeholder row, never read."""
    dt = means2d.dtype
    log_opac = torch.log(opacities.detach().to(dt))[:, None]
    gauss = torch.cat([means2d.detach(), conics.detach().to(dt), log_opac, colors.detach().to(dt)], dim=1)  # [N, 9]
    return gauss if gauss.shape[0] else gauss.new_zeros(1, COLUMNS)


def deform(F: torch.Tensor, cov0: torch.Tensor) -> torch.Tensor:  # [N, 3, 3], [N, 3, 3] -> [N, 3, 3]
    """½(S + Sᵀ), S = F Σ⁰ Fᵀ, of float32 or float64 CPU tensors of one dtype: `gaussians.deform_covariances`' torch
    expression, bit for bit (`_deform_kernel`), the drawn covariances of each CPU frame."""
    ensure_warp()
    mat = wp.mat33f if F.dtype == torch.float32 else wp.mat33d
    out = torch.empty(F.shape, dtype=F.dtype)
    wp.launch(
        _deform_kernel, F.shape[0], [wp.from_torch(t.contiguous(), dtype=mat) for t in (F, cov0, out)], device="cpu"
    )
    return out
