"""Turn a scene description (SDF, labels, colours) into a volumetric `GaussianSet`.

Particles come from a jittered grid inside the solid (`sampling.sample_count`), so each carries an
MPM volume ≈ h³. The outer layer (sdf > -h) becomes drawn surface Gaussians, moved onto the
surface along the normal and flattened along it; foliage labels keep a thicker drawn layer (2h)
of randomly tilted flat Gaussians; the rest are interior fill particles (`interior=True`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import torch

from ..io.gaussian_set import GaussianSet
from . import gaussians as G
from .sampling import sample_count
from .shapes import gradient

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class SceneSpec:
    """A built-in scene: a solid, its material labels and its colours (all in metres, z up)."""

    name: str
    lower: Vec3  # bounding box of the geometry (no particle outside)
    upper: Vec3
    paper_n: int  # particle count of the `paper` size
    sdf: Callable  # p [M, 3] -> signed distance [M], negative inside
    labels: Callable  # (p [M, 3], sdf [M], h) -> int32 labels [M], from the rest position
    colors: Callable  # (p [M, 3], labels [M], normals [M, 3], surface [M] bool, gen) -> rgb [M, 3]
    foliage: tuple = ()  # labels drawn as randomly tilted flat Gaussians in a 2h layer
    view_std: float = 0.03  # std of the higher SH bands (view dependence)


def _drop_to(n: int, surface: torch.Tensor, gen: torch.Generator) -> torch.Tensor:  # [M] -> idx
    """Indices that keep exactly n of M ≥ n particles, dropping random interior ones first."""
    m = len(surface)
    if m <= n:
        return torch.arange(m)
    inner = torch.nonzero(~surface).squeeze(1)
    pool = inner if len(inner) >= m - n else torch.arange(m)
    drop = pool[torch.randperm(len(pool), generator=gen)[: m - n]]
    keep = torch.ones(m, dtype=torch.bool)
    keep[drop] = False
    return torch.nonzero(keep).squeeze(1)


def _surface_frames(spec: SceneSpec, p, d, leafy, h, gen):
    """Normals [S, 3] and positions [S, 3] of the drawn particles (projected onto the surface
    unless foliage, whose normals are tilted at random)."""
    normals = gradient(spec.sdf, p, 0.1 * h)
    proj = p - d[:, None] * normals
    tilt = torch.nn.functional.normalize(normals + 1.5 * G.random_unit(len(p), gen), dim=-1)
    normals = torch.where(leafy[:, None], tilt, normals)
    pos = torch.where(leafy[:, None], p, proj)
    lo, hi = torch.tensor(spec.lower), torch.tensor(spec.upper)
    return normals, torch.minimum(torch.maximum(pos, lo), hi)


def build_scene(spec: SceneSpec, n: int, seed: int = 0, sh_degree: int = 1, device="cpu") -> GaussianSet:
    """Sample `spec` with n particles (exactly n unless the solid is too small) into a GaussianSet."""
    gen = torch.Generator().manual_seed(int(seed))
    p, d, h = sample_count(spec.sdf, spec.lower, spec.upper, n, gen)
    labels = spec.labels(p, d, h).to(torch.int32)
    leafy = torch.isin(labels, torch.tensor(spec.foliage, dtype=torch.int32))
    surface = (d > -h) | (leafy & (d > -2 * h))
    keep = _drop_to(n, surface, gen)
    p, d, labels, leafy, surface = p[keep], d[keep], labels[keep], leafy[keep], surface[keep]

    m, s = len(p), surface
    normals = torch.zeros(m, 3)
    normals[s], p[s] = _surface_frames(spec, p[s], d[s], leafy[s], h, gen)
    quats = torch.zeros(m, 4)
    quats[:, 0] = 1.0
    quats[s] = G.surface_quats(normals[s], gen)
    scales = torch.full((m, 3), 0.5 * h)
    scales[s] = G.surface_scales(int(s.sum()), h, gen)
    scales[s & leafy] *= torch.tensor([1.5, 0.9, 0.8])  # leaves: longer than wide
    opacities = torch.full((m,), G.INTERIOR_OPACITY)
    opacities[s] = G.opacity_from_logit(3.5, 0.8, int(s.sum()), gen)
    opacities[s & leafy] = G.opacity_from_logit(2.2, 0.8, int((s & leafy).sum()), gen)
    rgb = spec.colors(p, labels, normals, s, gen).clamp(0.0, 1.0)
    sh = G.rgb_to_sh(rgb, sh_degree, spec.view_std, gen)
    sh[~s, 1:] = 0.0  # interior particles: no view dependence
    gs = GaussianSet(means=p, quats=quats, scales=scales, opacities=opacities, sh=sh, interior=~s, labels=labels)
    return gs.to(device)
