"""Splatting 3D Gaussians: one entry point (`render`), three backends, one float64 reference.

Backends (DESIGN.md "Rendering"): gsplat's CUDA `rasterization` when the tensors live on a CUDA
device; on the CPU a Warp kernel (`raster_kernels`, one thread per tile) when no gradient is
needed, else a pure-torch tile rasterizer (differentiable, any device and dtype). All three share
the math below and the torch projection. The choice is made from the tensors' device, never by
trying to import gsplat: without a GPU, importing gsplat's CUDA code may start a slow, failing JIT
compile. gsplat and the Warp kernels are imported lazily, in their own branches only.

The math, identical to gsplat 1.5.3 (`ProjectionEWA3DGSFused.cu`, `RasterizeToPixels3DGSFwd.cu`):

* EWA projection (Zwicker et al. 2002): camera-space mean t = R x + t₀, Σ_c = R Σ Rᵀ,
  Σ₂ = J Σ_c Jᵀ + ε·I with J = [[f_x/z, 0, −f_x t_x/z²], [0, f_y/z, −f_y t_y/z²]] where
  t_x/z, t_y/z are clamped to the frustum widened by 30 % (≈ 1.3·tan(fov/2) for a centred
  principal point). Mean μ = (f_x x/z + c_x, f_y y/z + c_y). Culled when z ∉ [near, far] or
  det Σ₂ ≤ 0.
* `antialiased` mode (Mip-Splatting's 2D filter): opacity ← opacity · sqrt(det Σ₂⁰ / det Σ₂),
  Σ₂⁰ the covariance before adding ε·I.
* Screen extent: per-axis radius r_x = ⌈k sqrt(Σ₂,xx)⌉, r_y = ⌈k sqrt(Σ₂,yy)⌉ with the
  opacity-aware k = min(3.33, sqrt(2 ln(255·o))) (Radl et al. 2024, StopThePop, §B.2). This
  axis-aligned box circumscribes exactly the ellipse outside which α < 1/255, so tile culling
  never removes a contribution that compositing would keep. (gsplat < 1.4 used 3σ of the
  largest eigenvalue instead; 1.5.3, the pinned version, uses this.)
* Compositing over depth-sorted Gaussians (stable: ties by index), pixel centres (x+½, y+½):
  σ = ½ dᵀ Σ₂⁻¹ d, α = min(0.999, o e^{−σ}); skip α < 1/255; stop (exclusive) once
  T(1 − α) ≤ 1e-4; C = Σ c_i α_i T_i + T·background, alpha = 1 − T.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import torch
from torch import Tensor

from ..errors import RenderError
from .camera import Camera
from .warm_up import gsplat_ready, wait_for_gsplat

ALPHA_THRESHOLD = 1.0 / 255.0
T_THRESHOLD = 1e-4
ALPHA_MAX = 0.999
EXTEND_MAX = 3.33
TILE = 16  # gsplat's tile edge [px]; the torch backend uses it on CUDA
TILE_CPU = 8  # on the CPU: a Gaussian is evaluated at every pixel of the tiles its footprint touches,
# so 8-px tiles evaluate ~3x fewer (Gaussian, pixel) pairs (bread at 320x240 renders about 3x faster);
# pixels only differ where a 16-px tile let a Gaussian reach past its footprint (≤ 1/255 there).
# The Warp backend uses it too (4 and 16 px were slower on bread at 320x240: more list entries, more pairs)
MODES = ("classic", "antialiased")
BACKENDS = ("auto", "gsplat", "torch", "warp")
WARP_DTYPES = (torch.float32, torch.float64)  # the Warp kernels' overloads


@dataclass
class RenderOutput:
    image: Tensor  # [H, W, 3] float in [0, 1]
    alpha: Tensor  # [H, W] accumulated opacity 1 − T
    backend: str  # "gsplat", "torch", "warp" or "reference"


@dataclass
class Projection:
    means2d: Tensor  # [N, 2] pixel coordinates of the centres
    conics: Tensor  # [N, 3] upper triangle of Σ₂⁻¹: (a, b, c) = (inv00, inv01, inv11)
    depths: Tensor  # [N] camera-space z
    radii: Tensor  # [N, 2] int32 screen half-extents; (0, 0) = culled
    opacities: Tensor  # [N] effective opacity (× compensation in antialiased mode)
    compensations: Optional[Tensor]  # [N] sqrt(det Σ₂⁰ / det Σ₂), antialiased mode only
    covars2d: Tensor  # [N, 2, 2] Σ₂ including ε·I

    @property
    def visible(self) -> Tensor:  # [N] bool
        return (self.radii > 0).any(dim=-1)


def _check_mode(mode: str):
    if mode not in MODES:
        raise RenderError(f"render: mode must be one of {MODES}, got {mode!r}")


def project_gaussians(
    means: Tensor,  # [N, 3] world
    covars: Tensor,  # [N, 3, 3] world
    viewmat: Tensor,  # [4, 4] world → camera
    K: Tensor,  # [3, 3]
    width: int,
    height: int,
    eps2d: float = 0.3,
    near: float = 0.01,
    far: float = 1e10,
    mode: str = "classic",
    opacities: Optional[Tensor] = None,  # [N]; None → fixed extent 3.33σ, no opacity culling
) -> Projection:
    """EWA splatting projection, gsplat's `fully_fused_projection` (pinhole) in torch."""
    _check_mode(mode)
    viewmat, K = viewmat.to(means), K.to(means)
    R, t = viewmat[:3, :3], viewmat[:3, 3]
    mc = means @ R.T + t  # [N, 3]
    cc = R @ covars @ R.T  # [N, 3, 3]
    x, y, z = mc.unbind(-1)
    in_depth = (z >= near) & (z <= far)
    z = torch.where(in_depth, z, torch.ones_like(z))  # keep culled entries finite
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    lim_xp = (width - cx) / fx + 0.3 * (0.5 * width / fx)
    lim_xn = cx / fx + 0.3 * (0.5 * width / fx)
    lim_yp = (height - cy) / fy + 0.3 * (0.5 * height / fy)
    lim_yn = cy / fy + 0.3 * (0.5 * height / fy)
    tx = z * torch.minimum(lim_xp, torch.maximum(-lim_xn, x / z))
    ty = z * torch.minimum(lim_yp, torch.maximum(-lim_yn, y / z))
    zero = torch.zeros_like(z)
    J = torch.stack([fx / z, zero, -fx * tx / (z * z), zero, fy / z, -fy * ty / (z * z)], -1).reshape(-1, 2, 3)
    cov2d = J @ cc @ J.transpose(-1, -2)  # [N, 2, 2]
    means2d = torch.stack([fx * x / z + cx, fy * y / z + cy], dim=-1)

    det0 = cov2d[:, 0, 0] * cov2d[:, 1, 1] - cov2d[:, 0, 1] * cov2d[:, 1, 0]
    cov2d = cov2d + eps2d * torch.eye(2, dtype=means.dtype, device=means.device)
    det = cov2d[:, 0, 0] * cov2d[:, 1, 1] - cov2d[:, 0, 1] * cov2d[:, 1, 0]
    valid = in_depth & (det > 0)
    det_s = torch.where(valid, det, torch.ones_like(det))
    conics = torch.stack([cov2d[:, 1, 1] / det_s, -cov2d[:, 0, 1] / det_s, cov2d[:, 0, 0] / det_s], dim=-1)
    comp = torch.sqrt((det0 / det_s).clamp_min(0.0)) if mode == "antialiased" else None

    extend = torch.full_like(z, EXTEND_MAX)
    if opacities is not None:
        opacities = opacities.to(means) * comp if comp is not None else opacities.to(means)
        valid = valid & (opacities >= ALPHA_THRESHOLD)
        extend = torch.minimum(
            extend, torch.sqrt(2.0 * torch.log(opacities.clamp_min(ALPHA_THRESHOLD) / ALPHA_THRESHOLD))
        )
    else:
        opacities = comp if comp is not None else torch.ones_like(z)
    rx = torch.ceil(extend * torch.sqrt(cov2d[:, 0, 0].clamp_min(0.0)))
    ry = torch.ceil(extend * torch.sqrt(cov2d[:, 1, 1].clamp_min(0.0)))
    valid = valid & ((rx > 0) | (ry > 0))
    mx, my = means2d.unbind(-1)
    valid = valid & (mx + rx > 0) & (mx - rx < width) & (my + ry > 0) & (my - ry < height)
    radii = torch.where(valid[:, None], torch.stack([rx, ry], -1), torch.zeros_like(means2d)).int()
    return Projection(means2d, conics, mc[:, 2], radii, opacities, comp, cov2d)


def _depth_order(proj: Projection) -> Tensor:  # [V] int64
    """The visible Gaussians, nearest first (stable: ties by index)."""
    ids = torch.nonzero(proj.visible).squeeze(1)
    return ids[torch.sort(proj.depths[ids], stable=True).indices]


def _tile_intersections(proj: Projection, width: int, height: int, tile: int):
    """Depth-sorted (tile, Gaussian) pairs: returns gaussian ids sorted by (tile, depth) and the
    per-tile [start, count) ranges, like gsplat's `isect_tiles` + `isect_offset_encode`."""
    tw, th = (width + tile - 1) // tile, (height + tile - 1) // tile
    ids = _depth_order(proj)
    m, r = proj.means2d[ids] / tile, proj.radii[ids].to(proj.means2d.dtype) / tile
    x0 = torch.floor(m[:, 0] - r[:, 0]).clamp(0, tw).long()
    x1 = torch.ceil(m[:, 0] + r[:, 0]).clamp(0, tw).long()
    y0 = torch.floor(m[:, 1] - r[:, 1]).clamp(0, th).long()
    y1 = torch.ceil(m[:, 1] + r[:, 1]).clamp(0, th).long()
    span = x1 - x0
    counts = span * (y1 - y0)
    rep = torch.repeat_interleave(torch.arange(ids.numel(), device=ids.device), counts)
    local = torch.arange(rep.numel(), device=ids.device) - (torch.cumsum(counts, 0) - counts)[rep]
    tile_id = (y0[rep] + local // span[rep]) * tw + x0[rep] + local % span[rep]
    tile_id, order = torch.sort(tile_id, stable=True)  # stable: keeps depth order per tile
    flat = ids[rep[order]]
    tile_counts = torch.bincount(tile_id, minlength=tw * th)
    return flat, torch.cumsum(tile_counts, 0) - tile_counts, tile_counts, tw, th


def _composite_chunk(
    tiles, pos, counts, starts, flat_pad, pad_id, ox, oy, ar, mx, my, ca, cb, cc, log_opac, cols, T, acc
):
    """Composite Gaussians number `pos` [chunk] of each tile in `tiles` [A] into T [tiles, P] and
    acc [tiles, P, C] (in place). T < 0 marks a pixel that has stopped (|T| its transmittance)."""
    inside = pos[None, :] < counts[tiles, None]  # [A, chunk]
    g = flat_pad[torch.where(inside, starts[tiles, None] + pos[None, :], pad_id)]  # [A, chunk]
    u = ox[tiles, None, None] + ar - mx[g][..., None]  # [A, chunk, tile]: pixel x − μ_x
    v = oy[tiles, None, None] + ar - my[g][..., None]  # [A, chunk, tile]: pixel y − μ_y
    # ln α = ln o − σ, σ = ½a u² + ½c v² + b u v, built from per-row/column terms [A, chunk, tile]
    row = log_opac[g][..., None] - (0.5 * ca[g])[..., None] * u * u
    col = (0.5 * cc[g])[..., None] * v * v
    lin = cb[g][..., None] * u
    alpha = (row[:, :, None, :] - col[:, :, :, None]).sub_(lin[:, :, None, :] * v[:, :, :, None])
    alpha = alpha.exp_().clamp_max_(ALPHA_MAX).flatten(2)  # [A, chunk, P]
    alpha.masked_fill_(alpha < ALPHA_THRESHOLD, 0.0)
    T0 = T[tiles]  # [A, P]; stopped pixels are negative, so nothing below passes `keep`
    incl = torch.cumprod(1.0 - alpha, dim=1).mul_(T0[:, None, :])  # T after each Gaussian
    keep = incl > T_THRESHOLD  # a prefix of the chunk: gsplat's exclusive stop
    w = torch.cat([T0[:, None, :], incl[:, :-1]], dim=1).mul_(alpha).mul_(keep)  # α T_before, kept only
    acc[tiles] += torch.bmm(w.transpose(1, 2), cols[g])
    n_keep = keep.sum(dim=1, keepdim=True)  # [A, 1, P]
    T_last = torch.gather(incl, 1, (n_keep - 1).clamp_min(0)).squeeze(1)
    T_new = torch.where(n_keep.squeeze(1) > 0, T_last, T0)
    stopped = (n_keep.squeeze(1) < keep.shape[1]) & (T0 > T_THRESHOLD)
    T[tiles] = torch.where(stopped, -T_new, T_new)


def _composite_chunk_autograd(
    tiles, pos, counts, starts, flat_pad, pad_id, ox, oy, ar, mx, my, ca, cb, cc, log_opac, cols, T, acc
):
    """`_composite_chunk` without in-place operations, for autograd: returns the new (T, acc)."""
    inside = pos[None, :] < counts[tiles, None]
    g = flat_pad[torch.where(inside, starts[tiles, None] + pos[None, :], pad_id)]
    u = ox[tiles, None, None] + ar - mx[g][..., None]
    v = oy[tiles, None, None] + ar - my[g][..., None]
    row = log_opac[g][..., None] - (0.5 * ca[g])[..., None] * u * u
    col = (0.5 * cc[g])[..., None] * v * v
    lin = cb[g][..., None] * u
    alpha = (row[:, :, None, :] - col[:, :, :, None] - lin[:, :, None, :] * v[:, :, :, None]).exp()
    alpha = alpha.clamp_max(ALPHA_MAX).flatten(2)
    alpha = torch.where(alpha < ALPHA_THRESHOLD, torch.zeros_like(alpha), alpha)
    T0 = T[tiles]
    incl = torch.cumprod(1.0 - alpha, dim=1) * T0[:, None, :]
    keep = incl > T_THRESHOLD
    w = torch.cat([T0[:, None, :], incl[:, :-1]], dim=1) * alpha * keep
    acc = acc.index_add(0, tiles, torch.bmm(w.transpose(1, 2), cols[g]))
    n_keep = keep.sum(dim=1, keepdim=True)
    T_last = torch.gather(incl, 1, (n_keep - 1).clamp_min(0)).squeeze(1)
    T_new = torch.where(n_keep.squeeze(1) > 0, T_last, T0)
    stopped = (n_keep.squeeze(1) < keep.shape[1]) & (T0 > T_THRESHOLD)
    return T.index_copy(0, tiles, torch.where(stopped, -T_new, T_new)), acc


def rasterize_tiles(
    proj: Projection,
    colors: Tensor,  # [N, 3]
    width: int,
    height: int,
    background: Tensor,  # [3]
    tile: Optional[int] = None,  # tile edge [px]; default TILE on CUDA, TILE_CPU on the CPU
    chunk: Optional[int] = None,  # Gaussians per tile per step; default 32 on CPU, 128 on CUDA
    max_elems: Optional[int] = None,  # per-call temporaries cap (elements); default 2²³ CPU, 2²⁶ CUDA
) -> tuple[Tensor, Tensor]:  # [H, W, 3], [H, W]
    """Front-to-back compositing, all tiles at once, `chunk` Gaussians per tile per step.

    Per step every active tile evaluates its next `chunk` Gaussians at its tile² pixels:
    σ is separable in the tile's local (i, j) so σ = ½a u_i² + ½c v_j² + b u_i v_j is built from
    [chunk, tile] vectors; T_k = T₀ Π_{l≤k}(1 − α_l) is a cumprod; a Gaussian counts while
    T_k > 1e-4 (a prefix of the chunk, since T_k is non-increasing), giving gsplat's exclusive stop.
    """
    dev, dt = proj.means2d.device, proj.means2d.dtype
    chunk = chunk or (128 if dev.type == "cuda" else 32)
    tile = tile or (TILE if dev.type == "cuda" else TILE_CPU)
    flat, starts, counts, tw, th = _tile_intersections(proj, width, height, tile)
    n_tiles, P = tw * th, tile * tile
    T = torch.ones(n_tiles, P, dtype=dt, device=dev)
    acc = torch.zeros(n_tiles, P, colors.shape[-1], dtype=dt, device=dev)
    if flat.numel():
        # one padding Gaussian (index N) with zero opacity for ragged chunks
        n = proj.means2d.shape[0]
        mx = torch.cat([proj.means2d[:, 0], proj.means2d.new_zeros(1)])
        my = torch.cat([proj.means2d[:, 1], proj.means2d.new_zeros(1)])
        ca, cb, cc = (torch.cat([proj.conics[:, k], proj.conics.new_zeros(1)]) for k in range(3))
        log_opac = torch.log(torch.cat([proj.opacities, proj.opacities.new_zeros(1)]))  # pad: −inf
        cols = torch.cat([colors.to(dt), colors.new_zeros(1, colors.shape[-1]).to(dt)])
        ar = torch.arange(tile, dtype=dt, device=dev) + 0.5
        ox = (torch.arange(n_tiles, device=dev) % tw).to(dt) * tile
        oy = (torch.arange(n_tiles, device=dev) // tw).to(dt) * tile
        steps = torch.arange(chunk, device=dev)
        flat_pad = torch.cat([flat, flat.new_full((1,), n)])
        n_steps = int((counts.max().item() + chunk - 1) // chunk)
        max_elems = max_elems or (1 << 26 if dev.type == "cuda" else 1 << 23)
        batch = max(1, max_elems // (chunk * P))  # tiles per kernel call: caps temporaries
        active = torch.nonzero(counts > 0).squeeze(1)
        grad = torch.is_grad_enabled() and any(
            t.requires_grad for t in (proj.means2d, proj.conics, proj.opacities, colors)
        )
        for s in range(n_steps):
            for b0 in range(0, active.numel(), batch):
                args = (
                    active[b0 : b0 + batch],
                    s * chunk + steps,
                    counts,
                    starts,
                    flat_pad,
                    flat.numel(),
                    ox,
                    oy,
                    ar,
                    mx,
                    my,
                    ca,
                    cb,
                    cc,
                    log_opac,
                    cols,
                    T,
                    acc,
                )
                if grad:  # differentiable (fitting through the renderer): no in-place updates
                    T, acc = _composite_chunk_autograd(*args)
                else:
                    _composite_chunk(*args)
            alive = (counts[active] > (s + 1) * chunk) & (T[active] > 0).any(dim=1)
            active = active[alive]
            if active.numel() == 0:
                break
    T = T.abs()
    img = acc + T[..., None] * background.to(dt)
    img = img.reshape(th, tw, tile, tile, -1).permute(0, 2, 1, 3, 4).reshape(th * tile, tw * tile, -1)
    T = T.reshape(th, tw, tile, tile).permute(0, 2, 1, 3).reshape(th * tile, tw * tile)
    return img[:height, :width], 1.0 - T[:height, :width]


def _render_gsplat(means, covars, colors, opacities, camera, background, mode, eps2d, near, far):
    wait_for_gsplat()  # the one-time build a run started in the background (`warm_up`) ends first
    import gsplat  # lazy: only reached with CUDA tensors on a machine with a GPU

    render_colors, render_alphas, _ = gsplat.rasterization(
        means.float().contiguous(),
        None,
        None,
        opacities.float().contiguous(),
        colors.float().contiguous(),
        camera.viewmat.to(means.device, torch.float32)[None],
        camera.K.to(means.device, torch.float32)[None],
        camera.width,
        camera.height,
        near_plane=near,
        far_plane=far,
        eps2d=eps2d,
        packed=False,
        rasterize_mode=mode,
        covars=covars.float().contiguous(),
        backgrounds=background.to(means.device, torch.float32)[None],
    )
    return render_colors[0], render_alphas[0, ..., 0]


def _needs_grad(*tensors: Tensor) -> bool:
    return torch.is_grad_enabled() and any(t.requires_grad for t in tensors)


def rasterize_warp(
    proj: Projection,
    colors: Tensor,  # [N, 3]
    width: int,
    height: int,
    background: Tensor,  # [3]
    tile: int = TILE_CPU,  # tile edge [px]: which Gaussians a pixel visits, not how it composites them
) -> tuple[Tensor, Tensor]:  # [H, W, 3], [H, W]
    """`rasterize_tiles`' image on the CPU with Warp kernels (`raster_kernels`: the tile lists, then one thread per
    tile, each of its pixels composited on its own): forward only, float32 or float64."""
    from .raster_kernels import composite, tile_lists  # lazy: Warp loads with the first CPU render, not on import

    flat, starts, counts = tile_lists(_depth_order(proj), proj.means2d, proj.radii, width, height, tile)
    return composite(
        flat, starts, counts, proj.means2d, proj.conics, proj.opacities, colors, background, width, height, tile
    )


def check_backend(backend: str, device: str) -> None:
    """Refuse, before a run prepares anything, a `render.backend` that cannot draw on `device`: gsplat draws CUDA
    tensors only, the Warp rasterizer CPU tensors only (`render` would fail at the first frame)."""
    on_cuda = str(device).startswith("cuda")
    if backend == "gsplat" and not on_cuda:
        raise RenderError(
            f"render.backend = 'gsplat' draws on a CUDA device, but this run draws on {device}; "
            "use 'auto' (the Warp rasterizer on the CPU) or 'torch'"
        )
    if backend == "warp" and on_cuda:
        raise RenderError(
            f"render.backend = 'warp' draws on the CPU only, but this run draws on {device}; "
            "use 'auto' (gsplat on CUDA) or 'torch'"
        )


def auto_backend(on_cuda: bool, warp_ok: bool) -> str:
    """`auto`'s choice: gsplat for CUDA tensors once its one-time build is loaded (`warm_up.gsplat_ready`; the
    torch rasterizer while it builds or after it failed), the Warp kernel where it can draw (`warp_ok`: CPU
    float32/float64 tensors, no gradient), else the torch rasterizer."""
    if on_cuda:
        return "gsplat" if gsplat_ready() else "torch"
    return "warp" if warp_ok else "torch"


def render(
    means: Tensor,  # [N, 3] world positions
    covars: Tensor,  # [N, 3, 3] world covariances Σ = F Σ⁰ Fᵀ
    colors: Tensor,  # [N, 3] RGB (e.g. from `sh_colors`)
    opacities: Tensor,  # [N] in [0, 1]
    camera: Camera,
    background=(1.0, 1.0, 1.0),  # RGB in [0, 1]
    backend: str = "auto",  # "auto" | "gsplat" | "torch" | "warp"
    mode: str = "classic",  # "classic" | "antialiased"
    eps2d: float = 0.3,
    near: float = 0.01,
    far: float = 1e10,
) -> RenderOutput:
    """Render N Gaussians into camera.height × camera.width; see the module docstring for the math.

    `auto` picks gsplat iff the tensors are on CUDA and CUDA is available, and gsplat's one-time build is not
    running or failed in the background (`warm_up.gsplat_ready`: the torch backend draws meanwhile); on the CPU
    the Warp kernel for float32/float64 tensors when no gradient is needed; else the torch backend (which runs on
    any device and dtype, with autograd). `torch` forces the torch backend everywhere; `gsplat` waits for a
    build that runs."""
    _check_mode(mode)
    if backend not in BACKENDS:
        raise RenderError(f"render: backend must be one of {BACKENDS}, got {backend!r}")
    _check_inputs(means, covars, colors, opacities, camera, background)
    on_cuda = means.is_cuda and torch.cuda.is_available()
    grad = _needs_grad(means, covars, colors, opacities, camera.viewmat, camera.K)
    if backend == "auto":
        warp_ok = means.device.type == "cpu" and means.dtype in WARP_DTYPES and not grad
        backend = auto_backend(on_cuda, warp_ok)
    if backend == "gsplat" and not on_cuda:
        raise RenderError(
            "render: backend='gsplat' needs CUDA tensors on a machine with a GPU; "
            "use backend='torch' (or 'auto') for CPU tensors"
        )
    if backend == "warp" and (means.device.type != "cpu" or means.dtype not in WARP_DTYPES):
        raise RenderError(
            f"render: backend='warp' draws float32 or float64 CPU tensors, got {means.dtype} on {means.device}; "
            "use backend='auto' (or 'torch')"
        )
    if backend == "warp" and grad:
        raise RenderError("render: backend='warp' has no gradient; use backend='torch' (or 'auto') to differentiate")
    bg = torch.as_tensor(background, dtype=means.dtype, device=means.device).reshape(3)
    if backend == "gsplat":
        img, alpha = _render_gsplat(means, covars, colors, opacities, camera, bg, mode, eps2d, near, far)
    else:
        proj = project_gaussians(
            means, covars, camera.viewmat, camera.K, camera.width, camera.height, eps2d, near, far, mode, opacities
        )
        raster = rasterize_warp if backend == "warp" else rasterize_tiles
        img, alpha = raster(proj, colors, camera.width, camera.height, bg)
    return RenderOutput(img.clamp(0.0, 1.0), alpha, backend)


_RENDER_SHAPES = {"means": (3,), "covars": (3, 3), "colors": (3,), "opacities": ()}


def _check_inputs(means, covars, colors, opacities, camera, background) -> None:
    """render's arguments: tensors of one device with one row per Gaussian ([N, 3], [N, 3, 3], [N, 3], [N]) of
    real numbers, a Camera and an RGB background, else RenderError naming the argument."""
    given = {"means": means, "covars": covars, "colors": colors, "opacities": opacities}
    n = means.shape[0] if torch.is_tensor(means) and means.dim() else None
    for name, t in given.items():
        want = "[N" + "".join(f", {d}" for d in _RENDER_SHAPES[name]) + "]"
        if not torch.is_tensor(t):
            raise RenderError(f"render: {name} must be a torch tensor {want}, got {type(t).__name__}; pass a tensor.")
        if not (t.is_floating_point() and t.dim() == 1 + len(_RENDER_SHAPES[name])) or (
            tuple(t.shape[1:]) != _RENDER_SHAPES[name] or t.shape[0] != n
        ):
            raise RenderError(
                f"render: {name} has shape {list(t.shape)} and dtype {t.dtype}, not {want} floats with N = {n} (the "
                "number of means); pass one row per Gaussian."
            )
        if t.device != means.device:
            raise RenderError(f"render: {name} is on {t.device} but means on {means.device}; move them to one device.")
    if not isinstance(camera, Camera):
        raise RenderError(
            f"render: camera must be a Camera, got {type(camera).__name__}; make one with "
            "fracture_gs.render.look_at(eye, target) or orbit(...)."
        )
    try:
        bg = torch.as_tensor(background, dtype=torch.float64).reshape(-1)
    except (TypeError, ValueError, RuntimeError):
        bg = None
    if bg is None or bg.numel() != 3 or not bool(((bg >= 0) & (bg <= 1)).all()):
        raise RenderError(f"render: background = {background!r:.60} is not an RGB colour; pass 3 numbers in [0, 1].")


@torch.no_grad()
def render_reference(
    means: Tensor,  # [N, 3]
    covars: Tensor,  # [N, 3, 3]
    colors: Tensor,  # [N, 3]
    opacities: Tensor,  # [N]
    camera: Camera,
    background=(1.0, 1.0, 1.0),
    mode: str = "classic",
    eps2d: float = 0.3,
    near: float = 0.01,
    far: float = 1e10,
) -> RenderOutput:
    """Brute-force float64 reference: every pixel visits every Gaussian in depth order (no tiles,
    no screen-extent culling), with the compositing rules of the module docstring. O(N·H·W)."""
    f64 = dict(dtype=torch.float64, device=means.device)
    means, covars, colors, opacities = (a.to(**f64) for a in (means, covars, colors, opacities))
    proj = project_gaussians(
        means,
        covars,
        camera.viewmat.to(**f64),
        camera.K.to(**f64),
        camera.width,
        camera.height,
        eps2d,
        near,
        far,
        mode,
        None,
    )
    depth_ok = (proj.depths >= near) & (proj.depths <= far)
    det = proj.covars2d[:, 0, 0] * proj.covars2d[:, 1, 1] - proj.covars2d[:, 0, 1] ** 2
    ids = torch.nonzero(depth_ok & (det > 0)).squeeze(1)
    ids = ids[torch.sort(proj.depths[ids], stable=True).indices]
    opac = opacities * proj.compensations if mode == "antialiased" else opacities
    H, W = camera.height, camera.width
    py, px = torch.meshgrid(torch.arange(H, **f64) + 0.5, torch.arange(W, **f64) + 0.5, indexing="ij")
    T = torch.ones(H, W, **f64)
    done = torch.zeros(H, W, dtype=torch.bool, device=means.device)
    C = torch.zeros(H, W, 3, **f64)
    for g in ids.tolist():
        dx, dy = proj.means2d[g, 0] - px, proj.means2d[g, 1] - py
        a, b, c = proj.conics[g]
        sigma = 0.5 * (a * dx * dx + c * dy * dy) + b * dx * dy
        alpha = torch.clamp_max(opac[g] * torch.exp(-sigma), ALPHA_MAX)
        use = (sigma >= 0) & (alpha >= ALPHA_THRESHOLD) & ~done
        next_T = T * (1 - alpha)
        stop = use & (next_T <= T_THRESHOLD)
        done |= stop
        use &= ~stop
        C += torch.where(use, alpha * T, 0.0)[..., None] * colors[g]
        T = torch.where(use, next_T, T)
    img = C + T[..., None] * torch.as_tensor(background, **f64)
    return RenderOutput(img.clamp(0.0, 1.0), 1.0 - T, "reference")
