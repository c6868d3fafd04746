"""Interior fill for surface-only reconstructions: `fill_interior`.

A trained 3DGS scene puts its Gaussians on the visible surface; MPM needs mass inside. Method:

1. splat each Gaussian's opacity α·exp(-½ m²) (m = Mahalanobis distance, m ≤ 3) onto a voxel
   grid, with its standard deviations clamped to [½, `max_radius`/3] voxels so degenerate
   (1e-12) Gaussians still mark their own voxel and huge (1e6) ones cover at most a few voxels;
   each voxel also remembers the Gaussian that contributed most to it (its owner);
2. voxels with density ≥ `threshold` are occupied (the surface shell); a faint capture whose
   Gaussians never reach it uses half the median density at the Gaussians' own voxels instead;
3. closing (dilate, then erode, `closing` voxels) bridges small holes in the shell; a flood fill
   from the grid's border through free voxels marks the exterior; everything it cannot reach is
   solid (enclosed volume and shell); the fill voxels are the solid minus its outer layer, so the
   filled volume follows the middle of the shell. A surface that stays open after closing is
   flooded: the fill then finds almost nothing (`stats["fill_fraction"]` tells);
4. one particle per inside voxel, uniformly jittered in the voxel (spacing = voxel size), with
   the DC colour, label and extra properties of the owner of the nearest occupied voxel (exact
   Euclidean feature transform).

Bounds: the grid has at most `max_grid` voxels along its longest axis (default 256: ≤ 16.8 M
voxels, a few hundred MB of temporaries at most) and at most `max_particles` particles are added
(default 200,000); the voxel size grows until both hold. Cost is O(voxels + Σ splat footprints),
a few seconds for 200k Gaussians.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from ..io.gaussian_set import GaussianSet
from .gaussians import INTERIOR_OPACITY

_TINY = 1e-9
_IDX_BITS = 40  # owner key = quantized weight << 40 | Gaussian index


def _valid(gs: GaussianSet, min_opacity: float) -> torch.Tensor:  # -> [N] bool
    """Gaussians with finite parameters, positive scales, nonzero quaternions, α ≥ min_opacity."""
    ok = torch.isfinite(gs.means).all(1) & torch.isfinite(gs.quats).all(1)
    ok &= torch.isfinite(gs.scales).all(1) & (gs.scales > 0).all(1)
    ok &= torch.linalg.vector_norm(gs.quats, dim=1) > 0
    return ok & (gs.opacities >= min_opacity)


def _default_spacing(scales: torch.Tensor) -> float:  # [N, 3]
    """2 × median tangential std (geometric mean of the two largest scales): about the spacing
    of the surface Gaussians."""
    top2 = scales.sort(dim=1).values[:, 1:]
    return 2.0 * float(top2.prod(dim=1).sqrt().median())


class _Grid:
    """Voxels of size dv covering [lo, hi] with `pad` voxels of margin (row-major, z fastest)."""

    def __init__(self, lo: torch.Tensor, hi: torch.Tensor, dv: float, pad: int):
        self.dv = dv
        self.origin = lo - pad * dv  # [3] float64
        self.shape = [int(math.ceil(float(e) / dv)) + 1 + 2 * pad for e in (hi - lo)]
        self.strides = torch.tensor([self.shape[1] * self.shape[2], self.shape[2], 1])

    def numel(self) -> int:
        return self.shape[0] * self.shape[1] * self.shape[2]

    def centres(self, idx: torch.Tensor) -> torch.Tensor:  # [M, 3] int -> [M, 3] float64
        return self.origin + (idx.to(torch.float64) + 0.5) * self.dv


def _precisions(gs: GaussianSet, s: torch.Tensor) -> torch.Tensor:  # s [N, 3] -> [N, 6]
    """Unique entries (xx, yy, zz, xy, xz, yz) of Σ⁻¹ = R diag(1/s²) Rᵀ."""
    R = gs.rotations().to(s.dtype)  # [N, 3, 3]
    P = (R / (s * s)[:, None, :]) @ R.transpose(1, 2)
    return torch.stack([P[:, 0, 0], P[:, 1, 1], P[:, 2, 2], P[:, 0, 1], P[:, 0, 2], P[:, 1, 2]], 1)


def _splat(gs: GaussianSet, grid: _Grid, max_radius: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Density [X·Y·Z] = Σ_g α_g exp(-½ m²) over voxels with m ≤ 3, and owner [X·Y·Z] (index of
    the Gaussian with the largest term, -1 if none), looping over voxel offsets, not Gaussians."""
    s = (gs.scales.to(torch.float64) / grid.dv).clamp(0.5, max_radius / 3.0)  # [N, 3] voxels
    radius = torch.ceil(3.0 * s.max(dim=1).values).long().clamp(1, max_radius)  # [N]
    order = torch.argsort(radius, descending=True)  # Gaussians reaching offset k: a prefix
    s, radius = s[order], radius[order]
    P = _precisions(gs.subset(order), s).float().T.contiguous()  # [6, N] in voxel units
    xi = (gs.means[order].to(torch.float64) - grid.origin) / grid.dv  # [N, 3]
    base = torch.floor(xi).long()
    d0 = (base + 0.5 - xi).float().T.contiguous()  # [3, N] base voxel centre - mean, voxels
    flat0 = (base * grid.strides).sum(1)
    alpha = gs.opacities[order].float()
    reach = [int((radius >= k).sum()) for k in range(max_radius + 1)]
    density = torch.zeros(grid.numel(), dtype=torch.float32)
    owner = torch.full((grid.numel(),), -1, dtype=torch.int64)
    rng = range(-max_radius, max_radius + 1)
    for off in ((i, j, k) for i in rng for j in rng for k in rng):  # offsets, not particles
        m = reach[max(abs(c) for c in off)]
        dx, dy, dz = (d0[a, :m] + off[a] for a in range(3))
        p = P[:, :m]
        m2 = p[0] * dx * dx + p[1] * dy * dy + p[2] * dz * dz + 2 * (p[3] * dx * dy + p[4] * dx * dz + p[5] * dy * dz)
        hit = torch.nonzero(m2 <= 9.0).squeeze(1)
        w = alpha[hit] * torch.exp(-0.5 * m2[hit])
        flat = flat0[hit] + int((torch.tensor(off) * grid.strides).sum())
        density.index_add_(0, flat, w)
        key = (w * (1 << 20)).long() << _IDX_BITS | order[hit]
        owner.scatter_reduce_(0, flat, key, "amax")
    return density, torch.where(owner >= 0, owner & ((1 << _IDX_BITS) - 1), owner)


def _dilate6(m: torch.Tensor) -> torch.Tensor:  # [X, Y, Z] bool -> [X, Y, Z] bool
    """m or any of its 6 face neighbours."""
    out = m.clone()
    for axis in range(3):
        n = m.shape[axis]
        out.narrow(axis, 1, n - 1).logical_or_(m.narrow(axis, 0, n - 1))
        out.narrow(axis, 0, n - 1).logical_or_(m.narrow(axis, 1, n - 1))
    return out


def _close(occ: torch.Tensor, steps: int) -> torch.Tensor:  # [X, Y, Z] bool -> [X, Y, Z] bool
    """Morphological closing (`steps` dilations, then as many erosions, 26-neighbourhood): gaps in the
    shell narrower than about 2·steps voxels are bridged; the shell does not grow."""
    if steps <= 0:
        return occ
    x = occ[None, None].float()
    k = 2 * steps + 1
    grown = torch.nn.functional.max_pool3d(x, k, stride=1, padding=steps)
    shrunk = -torch.nn.functional.max_pool3d(-grown, k, stride=1, padding=steps)
    return (shrunk[0, 0] > 0.5) | occ


def _exterior(occ: torch.Tensor) -> torch.Tensor:  # [X, Y, Z] bool -> [X, Y, Z] bool
    """Unoccupied voxels reachable from the grid's border through face neighbours (a flood fill from
    outside: whatever it cannot reach is enclosed, however the shell folds): the components of the free
    voxels (6-connected) that touch the border."""
    from scipy import ndimage

    labels, _ = ndimage.label(~occ.numpy())
    border = np.concatenate([labels[[0, -1]].ravel(), labels[:, [0, -1]].ravel(), labels[:, :, [0, -1]].ravel()])
    outside = np.unique(border[border > 0])
    return torch.from_numpy(np.isin(labels, outside))


def _solid(
    occ: torch.Tensor, closing: int, seal_bottom: bool = False
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(fill voxels, solid voxels, enclosed voxels): solid = everything the closed shell encloses,
    shell included; enclosed = solid minus the (closed) shell: empty for an open surface; fill = solid
    minus its outer layer (voxels face-adjacent to the exterior), so the filled volume follows the
    middle of the shell rather than its outside. `seal_bottom`: a virtual floor at the lowest occupied
    layer (axis 2 is up) closes an object captured standing on the ground, whose underside no camera saw;
    the floor itself is not solid."""
    closed = _close(occ, closing)
    if seal_bottom and bool(closed.any()):
        z0 = int(torch.nonzero(closed.any(dim=0).any(dim=0)).min())
        floor = torch.zeros_like(closed)
        floor[:, :, z0] = True
        ext = _exterior(closed | floor)
        solid = ~ext & ~(floor & ~closed)
    else:
        ext = _exterior(closed)
        solid = ~ext
    return solid & ~_dilate6(ext), solid, solid & ~closed


def _nearest_occupied(occ: torch.Tensor, idx: torch.Tensor) -> torch.Tensor:  # idx [K, 3]
    """Flat index of the nearest occupied voxel to each voxel idx (exact Euclidean feature transform)."""
    from scipy import ndimage

    feat = ndimage.distance_transform_edt(~occ.numpy(), return_distances=False, return_indices=True)
    i = idx.numpy()
    near = torch.from_numpy(feat[:, i[:, 0], i[:, 1], i[:, 2]]).long()  # [3, K]
    return near[0] * (occ.shape[1] * occ.shape[2]) + near[1] * occ.shape[2] + near[2]


def _voxelize(gs, lo, hi, dv, pad, max_radius, threshold, closing=1, seal_bottom=False):
    """(grid, occupied [X,Y,Z] bool, owner [X·Y·Z], fill voxel indices [K, 3], solid voxel count) at voxel dv."""
    grid = _Grid(lo, hi, dv, pad)
    density, owner = _splat(gs, grid, max_radius)
    # a faint capture (many Gaussians of opacity ~0.05) may never reach `threshold`: then half the
    # median density at the Gaussians' own voxels marks the surface instead
    at = torch.floor((gs.means.to(torch.float64) - grid.origin) / grid.dv).long()
    surface = float(density[(at * grid.strides).sum(1)].median())
    occ = (density >= min(threshold, 0.5 * surface)).reshape(grid.shape)
    fill, solid, enclosed = _solid(occ, closing, seal_bottom)
    return grid, occ, owner, torch.nonzero(fill), (int(solid.sum()), int(enclosed.sum()))


def _interior_set(src: GaussianSet, pts: torch.Tensor, near: torch.Tensor, dv: float) -> GaussianSet:
    """Interior particles at pts [Q, 3] taking DC colour, label and extras from src[near];
    isotropic std dv/2, identity rotation, opacity INTERIOR_OPACITY, no view-dependent SH."""
    q = len(pts)
    sh = torch.zeros(q, src.sh.shape[1], 3, dtype=src.sh.dtype)
    sh[:, 0] = src.sh[near, 0]
    quats = torch.zeros(q, 4)
    quats[:, 0] = 1
    return GaussianSet(
        means=pts.float(),
        quats=quats,
        scales=torch.full((q, 3), 0.5 * dv),
        opacities=torch.full((q,), INTERIOR_OPACITY),
        sh=sh,
        interior=torch.ones(q, dtype=torch.bool),
        labels=src.labels[near],
        extra={k: v[near] for k, v in src.extra.items()},
    )


def _concat(a: GaussianSet, b: GaussianSet) -> GaussianSet:
    """a followed by b (same SH size and extra keys), on a's device and dtypes."""
    dev = a.device
    cat = lambda x, y: torch.cat([x, y.to(dev, x.dtype)])  # noqa: E731
    return GaussianSet(
        means=cat(a.means, b.means),
        quats=cat(a.quats, b.quats),
        scales=cat(a.scales, b.scales),
        opacities=cat(a.opacities, b.opacities),
        sh=cat(a.sh, b.sh),
        interior=cat(a.interior, b.interior),
        labels=cat(a.labels, b.labels),
        extra={k: cat(v, b.extra[k]) for k, v in a.extra.items()},
    )


MAX_GRID = 512
"""fill_interior's largest `max_grid` (voxels along the longest axis): 512³ voxels hold ≈ 0.5 GB of densities."""


def _check_args(gs, spacing, max_particles, max_grid, threshold, min_opacity, max_radius, closing) -> None:
    """fill_interior's arguments, each an ArgumentError naming it: a GaussianSet, a positive finite spacing (or
    None), whole counts in their ranges (the grid, and the padding `closing` and `max_radius` add around it,
    bound the memory), a positive threshold and an opacity cut in [0, 1)."""
    from ..errors import ArgumentError
    from ..io.ply import as_gaussians

    where = "assets.fill_interior"
    as_gaussians(where, gs)

    def whole(name, value, low, high, example):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not low <= value <= high:
            raise ArgumentError(
                f"{where}: {name} = {value!r:.40} must be a whole number from {low} to {high:,}; "
                f"pass e.g. {name}={example}."
            )

    def number(name, value, ok, rule, example):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or not ok(value):
            raise ArgumentError(f"{where}: {name} = {value!r:.40} must be {rule}; pass e.g. {name}={example}.")

    if spacing is not None:
        number("spacing", spacing, lambda v: v > 0, "a positive voxel size in metres, or None (automatic)", 0.005)
    whole("max_particles", max_particles, 0, 100_000_000, 200_000)
    whole("max_grid", max_grid, 8, MAX_GRID, 256)
    whole("max_radius", max_radius, 1, max_grid // 8, 3)
    whole("closing", closing, 0, max_grid // 8, 1)
    number("threshold", threshold, lambda v: v > 0, "a positive voxel density", 0.2)
    number("min_opacity", min_opacity, lambda v: 0 <= v < 1, "an opacity in [0, 1)", 0.05)


def _voxel_size(src: GaussianSet, spacing, ext: float, max_grid: int, pad: int) -> float:
    """Requested spacing (default: `_default_spacing`), at least ext / usable grid cells."""
    dv = spacing if spacing is not None else _default_spacing(src.scales.double())
    dv = float(dv) if math.isfinite(float(dv)) else 0.0
    return max(dv, ext / max(1, max_grid - 2 * pad - 1), _TINY)


def fill_interior(
    gs: GaussianSet,
    spacing: float | None = None,
    max_particles: int = 200_000,
    max_grid: int = 256,
    threshold: float = 0.2,
    min_opacity: float = 0.05,
    max_radius: int = 3,
    seed: int = 0,
    closing: int = 1,
    stats: dict | None = None,
    seal_bottom: bool = False,
) -> GaussianSet:
    """`gs` followed by interior particles (interior=True) filling the volume its Gaussians
    enclose (see the module doc).

    spacing: particle spacing = voxel size [m]; None = twice the median tangential std of the
    Gaussians. It is enlarged so that the grid has ≤ max_grid voxels per axis and ≤ max_particles
    particles are added. threshold: density (summed α·exp(-½m²)) of an occupied voxel. Gaussians
    with opacity < min_opacity or non-finite/degenerate parameters are ignored. max_radius: splat
    radius cap in voxels. closing: shell gaps up to about 2·closing voxels are bridged before the
    flood fill; seal_bottom closes an object standing on the ground whose underside was never seen (a virtual
    floor at its lowest layer, z up). Deterministic for a given seed (it only drives the jitter). `stats`, if given,
    receives `added`, `spacing`, `solid_voxels`, `fill_voxels`, `fill_fraction` (fill / solid) and
    `enclosed_fraction` (solid voxels that are not shell / solid: near 0 for an open surface)."""
    _check_args(gs, spacing, max_particles, max_grid, threshold, min_opacity, max_radius, closing)
    if stats is not None:
        stats.update(added=0, spacing=None, solid_voxels=0, fill_voxels=0, fill_fraction=0.0, enclosed_fraction=0.0)
    ok = _valid(gs, min_opacity)
    if not ok.any() or max_particles < 1:
        return gs
    src = gs.subset(ok).to("cpu")
    means = src.means.to(torch.float64)
    lo, hi = means.min(0).values, means.max(0).values
    pad = max(max_radius, closing) + 2
    ext = max(float((hi - lo).max()), _TINY)
    dv = _voxel_size(src, spacing, ext, max_grid, pad)

    def voxelize(d):
        return _voxelize(src, lo, hi, d, pad, max_radius, threshold, closing, seal_bottom)

    coarse = max(dv, ext / max(1, min(max_grid, 64) - 2 * pad - 1))
    if coarse > dv:  # estimate the inside volume on a coarse grid to respect the budget at once
        inside = len(voxelize(coarse)[3])
        dv = max(dv, (inside / max_particles) ** (1 / 3) * coarse)
    grid, occ, owner, idx, solid = voxelize(dv)
    for _ in range(3):  # coarsen until the particle budget holds
        if len(idx) <= max_particles:
            break
        dv *= (len(idx) / max_particles) ** (1 / 3) * 1.02
        grid, occ, owner, idx, solid = voxelize(dv)
    gen = torch.Generator().manual_seed(int(seed))
    if stats is not None:
        solid, enclosed = solid
        stats.update(
            spacing=dv,
            solid_voxels=solid,
            fill_voxels=len(idx),
            fill_fraction=len(idx) / max(solid, 1),
            enclosed_fraction=enclosed / max(solid, 1),
        )
    if len(idx) > max_particles:
        idx = idx[torch.randperm(len(idx), generator=gen)[:max_particles].sort().values]
    if len(idx) == 0:
        return gs
    near_voxel = _nearest_occupied(occ, idx)
    near = owner[near_voxel]
    jitter = torch.rand(len(idx), 3, generator=gen, dtype=torch.float64) - 0.5
    pts = grid.centres(idx) + jitter * dv
    if stats is not None:
        stats["added"] = len(idx)
    return _concat(gs, _interior_set(src, pts, near, dv))


def solid_voxels(
    gs: GaussianSet,
    spacing: float,
    threshold: float = 0.2,
    min_opacity: float = 0.05,
    closing: int = 1,
    seal_bottom: bool = False,
) -> torch.Tensor:  # -> [X, Y, Z] bool
    """The object as voxels of size `spacing` [m]: its shell and everything the shell encloses (steps 1–3 of
    the module doc), e.g. to measure how thick its parts are. Empty (0, 0, 0) when no Gaussian is valid."""
    ok = _valid(gs, min_opacity)
    if not ok.any():
        return torch.zeros(0, 0, 0, dtype=torch.bool)
    src = gs.subset(ok).to("cpu")
    means = src.means.to(torch.float64)
    lo, hi = means.min(0).values, means.max(0).values
    pad = max(3, closing) + 2
    grid, occ, *_ = _voxelize(src, lo, hi, spacing, pad, 3, threshold, closing)
    return _solid(occ, closing, seal_bottom)[1]
