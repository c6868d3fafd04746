"""Signed distance functions (negative inside, metres) and small vector helpers for the assets.

All functions take points `p` [M, 3] (float32 torch) and return distances [M]. Formulas are the
standard exact SDFs (box, capsule, capped cone) and first-order ones (ellipsoid, smooth min/max);
the built-in scenes combine them with `union`/`smooth_max`.
"""

from __future__ import annotations

import math

import torch


def _length(v: torch.Tensor) -> torch.Tensor:  # [M, D] -> [M]
    return torch.linalg.vector_norm(v, dim=-1)


def box(p: torch.Tensor, lower, upper) -> torch.Tensor:  # p [M, 3] -> [M]
    """Exact SDF of the axis-aligned box [lower, upper]."""
    lo, hi = p.new_tensor(lower), p.new_tensor(upper)
    q = (p - 0.5 * (lo + hi)).abs() - 0.5 * (hi - lo)
    return _length(q.clamp_min(0)) + q.max(dim=-1).values.clamp_max(0)


def rounded_rect_xy(p: torch.Tensor, center, half, radius: float) -> torch.Tensor:  # [M, 3] -> [M]
    """Exact 2D SDF in (x, y) of a rectangle with half-extents `half` and corners rounded by
    `radius` (the rounded shape stays inside center ± half); z is ignored (an infinite prism)."""
    c, h = p.new_tensor(center), p.new_tensor(half)
    q = (p[:, :2] - c).abs() - (h - radius)
    return _length(q.clamp_min(0)) + q.max(dim=-1).values.clamp_max(0) - radius


def ellipsoid(p: torch.Tensor, center, radii) -> torch.Tensor:  # [M, 3] -> [M]
    """First-order SDF of an axis-aligned ellipsoid: k0 (k0 - 1) / k1 with k0 = |q/r|, k1 = |q/r²|
    (exact on the surface and for spheres)."""
    r = p.new_tensor(radii)
    q = p - p.new_tensor(center)
    k0 = _length(q / r)
    k1 = _length(q / (r * r)).clamp_min(1e-12)
    return k0 * (k0 - 1.0) / k1


def capsule(p: torch.Tensor, a, b, radius) -> torch.Tensor:  # [M, 3] -> [M]
    """Exact SDF of the segment a-b swept by a sphere; `radius` may be a pair (ra, rb), linearly
    interpolated along the segment (a tapered capsule; exact when ra == rb)."""
    a, b = p.new_tensor(a), p.new_tensor(b)
    ab = b - a
    t = ((p - a) @ ab / (ab @ ab)).clamp(0.0, 1.0)
    ra, rb = (radius, radius) if isinstance(radius, (int, float)) else radius
    return _length(p - a - t[:, None] * ab) - (ra + (rb - ra) * t)


def capped_cone_z(p: torch.Tensor, center_xy, z0: float, z1: float, r0: float, r1: float) -> torch.Tensor:
    """Exact SDF of a truncated cone about the vertical axis through `center_xy`, from z0 (radius
    r0) to z1 (radius r1)."""
    hh = 0.5 * (z1 - z0)
    q_r = _length(p[:, :2] - p.new_tensor(center_xy))
    q_z = p[:, 2] - 0.5 * (z0 + z1)
    r_at = torch.where(q_z < 0, torch.full_like(q_r, r0), torch.full_like(q_r, r1))
    ca_r = q_r - torch.minimum(q_r, r_at)
    ca_z = q_z.abs() - hh
    k2_r, k2_z = r1 - r0, 2.0 * hh
    t = (((r1 - q_r) * k2_r + (hh - q_z) * k2_z) / (k2_r * k2_r + k2_z * k2_z)).clamp(0.0, 1.0)
    cb_r = q_r - r1 + k2_r * t
    cb_z = q_z - hh + k2_z * t
    sign = torch.where((cb_r < 0) & (ca_z < 0), -1.0, 1.0)
    return sign * torch.sqrt(torch.minimum(ca_r**2 + ca_z**2, cb_r**2 + cb_z**2))


def smooth_min(a: torch.Tensor, b: torch.Tensor, k: float) -> torch.Tensor:  # [M], [M] -> [M]
    """Polynomial smooth minimum (≤ min(a, b)): a smooth union with blend radius k."""
    h = (0.5 + 0.5 * (b - a) / k).clamp(0.0, 1.0)
    return b + (a - b) * h - k * h * (1.0 - h)


def smooth_max(a: torch.Tensor, b: torch.Tensor, k: float) -> torch.Tensor:  # [M], [M] -> [M]
    """Polynomial smooth maximum (≥ max(a, b)): a smooth intersection that only removes material."""
    return -smooth_min(-a, -b, k)


def union(*ds: torch.Tensor) -> torch.Tensor:  # k × [M] -> [M]
    """Union of solids: pointwise minimum of their SDFs."""
    return torch.stack(ds).min(dim=0).values


def rotate_y(p: torch.Tensor, center, degrees: float) -> torch.Tensor:  # [M, 3] -> [M, 3]
    """Points rotated by `degrees` about the y axis through `center` (right-handed: +x tips to -z)."""
    c = p.new_tensor(center)
    t = math.radians(degrees)
    R = p.new_tensor([[math.cos(t), 0.0, math.sin(t)], [0.0, 1.0, 0.0], [-math.sin(t), 0.0, math.cos(t)]])
    return (p - c) @ R.T + c


def gradient(sdf, p: torch.Tensor, eps: float) -> torch.Tensor:  # [M, 3] -> [M, 3]
    """Unit outward normals ∇sdf/|∇sdf| by central differences with step eps."""
    g = torch.empty_like(p)
    for axis in range(3):  # three axes, not particles
        d = torch.zeros(3, dtype=p.dtype)
        d[axis] = eps
        g[:, axis] = sdf(p + d) - sdf(p - d)
    return torch.nn.functional.normalize(g, dim=-1, eps=1e-12)


def smooth_noise(p: torch.Tensor, gen: torch.Generator, freq: float, waves: int = 8) -> torch.Tensor:
    """Band-limited random field over space with zero mean and unit variance: a sum of `waves`
    cosines with random directions, wavelengths around 1/freq metres and random phases
    (deterministic per generator)."""
    k = torch.randn(waves, 3, generator=gen)
    k = torch.nn.functional.normalize(k, dim=-1) * (2 * math.pi * freq)
    k = k * (0.6 + 0.8 * torch.rand(waves, 1, generator=gen))
    phase = 2 * math.pi * torch.rand(waves, generator=gen)
    return torch.cos(p @ k.T.to(p.dtype) + phase.to(p.dtype)).sum(dim=-1) * math.sqrt(2.0 / waves)
