"""Cracks that show: drawn Gaussians trimmed to their own side of a fracture surface (`CrackFaces`).

A captured surface Gaussian can be several millimetres wide; when a crack runs through it, it belongs to one
fragment (the one of the particle carrying it) but its footprint still covers the other side, so the opening
stays hidden under it until the pieces are far apart, and then it looks torn rather than cracked. At each
fracture event, in the rest frame where Σ⁰ lives:

1. for Gaussian g of fragment f (its carrying particle's), the nearest particle b of another fragment among its
   k nearest particles at rest, and the nearest particle a of its own fragment, give the local crack surface:
   the bisector plane of a and b, normal n = (x_b − x_a)/|x_b − x_a|, at distance d = (m − x_g)·n from g's
   centre (m the midpoint);
2. g's extent across that plane, 2σ_n with σ_n² = nᵀΣ⁰n, is shrunk to d when it reaches past it: Σ⁰ ← A Σ⁰ Aᵀ
   with A = I + (s − 1) n nᵀ and s = clamp(d / 2σ_n, S_MIN, 1), which scales the Gaussian along n only (its
   extent along n becomes s·σ_n, the others stay);
3. a Gaussian whose centre lies past the bisector (d ≤ 0) is shrunk by S_MIN.

Gaussians far from any other fragment (no such b among their k nearest particles) are untouched, so an intact
piece keeps its look; the rendered covariance stays F Σ⁰ Fᵀ with the trimmed Σ⁰.
"""

from __future__ import annotations

from typing import Optional

import torch

S_MIN = 0.2
"""Smallest scale factor across a crack (a Gaussian is never shrunk to nothing)."""
NEIGHBOURS = 8
"""Nearest particles at rest examined per Gaussian."""


class CrackFaces:
    """Rest covariances trimmed at the fracture surfaces of a run (see the module doc).

    means0: the drawn Gaussians' rest positions [G, 3]; cov0: their rest covariances [G, 3, 3]; x0: the
    simulated particles' rest positions [P, 3]; index: the carrying particle of each Gaussian [G] (None: the
    Gaussians are the particles)."""

    def __init__(self, means0: torch.Tensor, cov0: torch.Tensor, x0: torch.Tensor, index: Optional[torch.Tensor]):
        from scipy.spatial import cKDTree

        self.cov0 = cov0
        self.means0 = means0.detach().to(torch.float64)
        self.x0 = x0.detach().to(torch.float64)
        k = min(NEIGHBOURS, len(x0))
        _, near = cKDTree(self.x0.cpu().numpy()).query(self.means0.cpu().numpy(), k=k)
        self.near = torch.as_tensor(near, dtype=torch.int64, device=cov0.device).reshape(len(means0), k)  # [G, k]
        self.index = index if index is not None else torch.arange(len(means0), device=cov0.device)
        self.trimmed_count = 0

    def trimmed(self, fragment: torch.Tensor) -> torch.Tensor:  # [P] int32 -> [G, 3, 3]
        """Σ⁰ of every drawn Gaussian, trimmed at the surfaces between the particles' `fragment` labels."""
        dev = self.cov0.device
        fragment = fragment.to(dev)
        own = fragment[self.index]  # [G]
        nf = fragment[self.near]  # [G, k]
        x0, m0 = self.x0.to(dev), self.means0.to(dev)
        d2 = ((x0[self.near] - m0[:, None, :]) ** 2).sum(-1)  # [G, k]
        inf = torch.finfo(d2.dtype).max
        other = (nf != own[:, None]) & (nf >= 0) & (own[:, None] >= 0)
        same = nf == own[:, None]
        b = torch.where(other, d2, inf).argmin(1)  # [G]
        a = torch.where(same, d2, inf).argmin(1)
        hit = other.any(1) & same.any(1)
        rows = torch.nonzero(hit).flatten()
        self.trimmed_count = 0
        if len(rows) == 0:
            return self.cov0
        xa = x0[self.near[rows, a[rows]]]
        xb = x0[self.near[rows, b[rows]]]
        n = torch.nn.functional.normalize(xb - xa, dim=1)  # [R, 3]
        d = ((0.5 * (xa + xb) - m0[rows]) * n).sum(1)  # [R] distance of the centre to the bisector
        S = self.cov0[rows].to(torch.float64)
        sigma_n = torch.sqrt((n[:, None, :] @ S @ n[:, :, None])[:, 0, 0].clamp_min(1e-30))
        s = torch.where(d > 0, (d / (2.0 * sigma_n)).clamp(S_MIN, 1.0), torch.full_like(d, S_MIN))
        cut = s < 1.0
        rows, n, s, S = rows[cut], n[cut], s[cut], S[cut]
        A = torch.eye(3, dtype=S.dtype, device=dev) + (s - 1.0)[:, None, None] * (n[:, :, None] @ n[:, None, :])
        out = self.cov0.clone()
        out[rows] = (A @ S @ A.transpose(1, 2)).to(out.dtype)
        self.trimmed_count = len(rows)
        return out
