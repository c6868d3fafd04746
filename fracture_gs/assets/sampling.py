"""Evenly spaced particles inside a solid given by an SDF: a jittered grid, culled coarse-to-fine.

A jittered grid (one point uniformly placed in each cell of side h: stratified sampling) keeps
every particle's MPM volume ≈ h³ and makes the expected count in any region exactly its volume
over h³ (so equal-density parts get particle counts in the ratio of their volumes), while avoiding
grid-aligned artefacts. Blocks of `BLOCK`³ cells whose centre lies
farther outside than the block's half-diagonal are skipped, so the SDF is evaluated only near the
solid (the paper-size scenes sample in about a second).
"""

from __future__ import annotations

import math
from typing import Callable

import torch

JITTER = 0.5  # jitter amplitude as a fraction of the spacing (0.5: anywhere in the cell)
BLOCK = 4  # cells per coarse block edge
CHUNK = 1 << 20  # points per SDF evaluation (bounds temporary memory)

Sdf = Callable[[torch.Tensor], torch.Tensor]  # [M, 3] -> [M]


def eval_chunked(sdf: Sdf, p: torch.Tensor) -> torch.Tensor:  # [M, 3] -> [M]
    """sdf(p) in chunks of CHUNK points."""
    if len(p) <= CHUNK:
        return sdf(p)
    return torch.cat([sdf(c) for c in p.split(CHUNK)])


def _lattice(lower: torch.Tensor, counts: list, step: float, offset: torch.Tensor) -> torch.Tensor:
    """Cell centres lower + offset + (i + ½)·step for i in [0, counts) per axis: [∏counts, 3]."""
    axes = [lower[a] + offset[a] + (torch.arange(counts[a], dtype=torch.float32) + 0.5) * step for a in range(3)]
    return torch.stack(torch.meshgrid(*axes, indexing="ij"), dim=-1).reshape(-1, 3)


def jittered_inside(sdf: Sdf, lower, upper, h: float, gen: torch.Generator, lipschitz: float = 1.5):
    """Points of a jittered grid of spacing h that are inside the solid (sdf < 0) and inside the
    box [lower, upper]; returns (points [M, 3], sdf values [M])."""
    lo, hi = torch.tensor(lower, dtype=torch.float32), torch.tensor(upper, dtype=torch.float32)
    big = BLOCK * h
    counts = [max(1, math.ceil(float(hi[a] - lo[a]) / big) + 1) for a in range(3)]
    offset = -torch.rand(3, generator=gen) * big  # random global shift of the lattice
    centres = _lattice(lo, counts, big, offset)  # [B, 3] block centres
    reach = lipschitz * (math.sqrt(3) * 0.5 * big + JITTER * h)
    centres = centres[eval_chunked(sdf, centres) < reach]
    sub = _lattice(torch.full((3,), -0.5 * big), [BLOCK] * 3, h, torch.zeros(3))  # [BLOCK³, 3]
    pts = (centres[:, None, :] + sub[None]).reshape(-1, 3)
    pts = pts + (torch.rand(pts.shape, generator=gen) * 2 - 1) * (JITTER * h)
    pts = pts[((pts >= lo) & (pts <= hi)).all(dim=1)]
    d = eval_chunked(sdf, pts)
    keep = d < 0
    return pts[keep], d[keep]


def estimate_volume(sdf: Sdf, lower, upper, res: int = 64) -> float:
    """Volume of {sdf < 0} inside the box, by stratified sampling on a res³ lattice [m³]."""
    lo, hi = torch.tensor(lower, dtype=torch.float32), torch.tensor(upper, dtype=torch.float32)
    ext = hi - lo
    step = float(ext.max()) / res
    counts = [max(1, math.ceil(float(ext[a]) / step)) for a in range(3)]
    pts = _lattice(lo, counts, step, torch.zeros(3))
    pts = pts[(pts <= hi).all(dim=1)]
    return float((eval_chunked(sdf, pts) < 0).sum()) * step**3


def sample_count(sdf: Sdf, lower, upper, n: int, gen: torch.Generator, tries: int = 8):
    """A jittered grid inside the solid with n to 1.03 n points when possible (else the closest
    try): the spacing h = (V / n)^(1/3) from the estimated volume V, refined from the realized
    counts. Returns (points [M, 3], sdf [M], h)."""
    h = (estimate_volume(sdf, lower, upper) / (1.015 * n)) ** (1 / 3)
    best, miss = None, float("inf")
    for _ in range(tries):
        pts, d = jittered_inside(sdf, lower, upper, h, gen)
        m = len(pts)
        off = 0.0 if n <= m <= 1.03 * n else abs(m / n - 1.015)
        if off < miss:
            best, miss = (pts, d, h), off
        if off == 0.0 or m == 0:
            break
        h *= (m / (1.015 * n)) ** (1 / 3)
    return best
