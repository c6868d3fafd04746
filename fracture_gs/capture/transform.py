"""Similarity transforms of Gaussian scenes: x' = s·Q·x + o, applied to every Gaussian consistently.

A Gaussian (mean μ, rotation R_g, scales σ, SH coefficients c) maps to (s Q μ + o, Q R_g, s σ, c')
with c' the SH of the rotated radiance: colour'(d) = colour(Qᵀ d). SH bands do not mix under a
rotation, so c' = M c with M block-diagonal; M is found numerically per rotation by fitting the
rotated basis on fixed sample directions (exact up to round-off for every degree ≤ 3, and it
uses the renderer's own basis, so the sign conventions agree by construction).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from ..io.gaussian_set import GaussianSet, quat_mul
from ..linalg import eigh_chunked
from ..render.gaussians import sh_basis


def _sample_dirs(n: int = 64) -> torch.Tensor:  # [n, 3] float64, a Fibonacci sphere
    i = torch.arange(n, dtype=torch.float64) + 0.5
    z = 1 - 2 * i / n
    r = (1 - z * z).sqrt()
    phi = i * math.pi * (3 - math.sqrt(5))
    return torch.stack([r * phi.cos(), r * phi.sin(), z], 1)


def rotate_sh(sh: torch.Tensor, R: torch.Tensor, chunk: int = 65536) -> torch.Tensor:
    """SH coefficients of the radiance rotated by R: the result evaluated at d equals `sh` evaluated
    at Rᵀd. sh [N, K, 3]; R [3, 3] or [N, 3, 3]; returns [N, K, 3] in sh's dtype."""
    K = sh.shape[1]
    degree = int(round(K**0.5)) - 1
    if degree == 0 or len(sh) == 0:
        return sh.clone()
    dirs = _sample_dirs().to(sh.device)  # [S, 3]
    pinv = torch.linalg.pinv(sh_basis(dirs, degree))  # [K, S]
    R = R.to(sh.device, torch.float64)
    out = torch.empty_like(sh)
    for a in range(0, len(sh), chunk):
        b = min(a + chunk, len(sh))
        Rc = R if R.dim() == 2 else R[a:b]
        rotated = torch.einsum("...ji,sj->...si", Rc, dirs)  # Rᵀ d  [S, 3] or [n, S, 3]
        basis = sh_basis(rotated.reshape(-1, 3), degree).reshape(*rotated.shape[:-1], K)
        A = pinv @ basis  # [K, K] or [n, K, K]: Y(Rᵀd) = Y(d) A, so Σ_b c_b Y_b(Rᵀd) = Σ_a Y_a(d) (A c)_a
        out[a:b] = (A @ sh[a:b].to(torch.float64)).to(sh.dtype)
    return out


def quat_from_matrix(R: torch.Tensor) -> torch.Tensor:  # [..., 3, 3] -> [..., 4] wxyz, w ≥ 0
    """Unit quaternion of a rotation matrix (Shepperd's method: the largest of 4 candidates)."""
    m = R.to(torch.float64)
    t = torch.stack(
        [
            1 + m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2],
            1 + m[..., 0, 0] - m[..., 1, 1] - m[..., 2, 2],
            1 - m[..., 0, 0] + m[..., 1, 1] - m[..., 2, 2],
            1 - m[..., 0, 0] - m[..., 1, 1] + m[..., 2, 2],
        ],
        -1,
    )
    k = t.argmax(-1, keepdim=True)
    s = 0.5 / t.gather(-1, k).clamp_min(1e-30).sqrt()
    w = torch.stack(
        [t[..., 0], m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], -1
    )
    x = torch.stack(
        [m[..., 2, 1] - m[..., 1, 2], t[..., 1], m[..., 1, 0] + m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0]], -1
    )
    y = torch.stack(
        [m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] + m[..., 0, 1], t[..., 2], m[..., 2, 1] + m[..., 1, 2]], -1
    )
    z = torch.stack(
        [m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0], m[..., 2, 1] + m[..., 1, 2], t[..., 3]], -1
    )
    q = torch.stack([c.gather(-1, k).squeeze(-1) for c in (w, x, y, z)], -1) * s
    q = torch.nn.functional.normalize(q, dim=-1)
    return torch.where(q[..., :1] < 0, -q, q)


def gaussians_from_covariances(cov: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(quats [N, 4] wxyz, scales [N, 3]) with R diag(s²) Rᵀ = cov ([N, 3, 3], symmetric PSD)."""
    lam, V = eigh_chunked(cov.to(torch.float64))
    flip = torch.linalg.det(V) < 0
    V[flip, :, 2] *= -1  # a proper rotation
    return quat_from_matrix(V).to(cov.dtype), lam.clamp_min(1e-20).sqrt().to(cov.dtype)


@dataclass
class SceneTransform:
    """x' = scale · rotation · x + offset (scene coordinates → simulation metres)."""

    scale: float
    rotation: torch.Tensor  # [3, 3] float64, proper rotation
    offset: torch.Tensor  # [3] float64

    def points(self, x: torch.Tensor) -> torch.Tensor:  # [N, 3] -> [N, 3]
        y = self.scale * (x.to(torch.float64) @ self.rotation.T.to(x.device)) + self.offset.to(x.device)
        return y.to(x.dtype)

    def inverse(self) -> SceneTransform:
        Qt = self.rotation.T.contiguous()
        return SceneTransform(1.0 / self.scale, Qt, -(Qt @ self.offset) / self.scale)

    def gaussians(self, gs: GaussianSet) -> GaussianSet:
        """Every Gaussian moved, rotated and scaled; SH rotated so colours follow the rotation."""
        Q = self.rotation.to(gs.means.device)
        qR = quat_from_matrix(Q)[None].to(gs.quats.dtype)
        return gs.replace(
            means=self.points(gs.means),
            quats=quat_mul(qR.expand_as(gs.quats), gs.quats),
            scales=gs.scales * self.scale,
            sh=rotate_sh(gs.sh, Q),
        )

    def to_config(self) -> dict:
        return {
            "scale": float(self.scale),
            "rotation": tuple(tuple(float(v) for v in row) for row in self.rotation.tolist()),
            "offset": tuple(float(v) for v in self.offset.tolist()),
        }
