"""Gaussian attributes for sampled particles: surface-aligned or random flat frames, scales, SH.

Conventions (shared by the built-in scenes and the interior fill):
  * a surface Gaussian's local z axis is the surface normal; its tangential standard deviations
    are ≈ 0.6 h (h = particle spacing) and its normal one ≈ h/12, so neighbours overlap into a
    closed skin despite the jitter;
  * interior particles are isotropic with standard deviation h/2 and identity rotation;
  * colours are RGB in [0, 1]; SH DC = (rgb - ½) / SH_C0 and higher bands get small random terms.
"""

from __future__ import annotations

import math

import torch

from ..io.gaussian_set import quat_mul
from ..sh import SH_C0

INTERIOR_OPACITY = 0.95


def quat_z_to(n: torch.Tensor) -> torch.Tensor:  # [M, 3] unit -> [M, 4]
    """The shortest-arc rotation taking e_z to n: normalize(1 + n_z, -n_y, n_x, 0); for n = -e_z,
    a half turn about x."""
    q = torch.stack([1 + n[:, 2], -n[:, 1], n[:, 0], torch.zeros_like(n[:, 0])], dim=-1)
    flip = q[:, 0] < 1e-6
    q[flip] = q.new_tensor([0.0, 1.0, 0.0, 0.0])
    return torch.nn.functional.normalize(q, dim=-1)


def surface_quats(normals: torch.Tensor, gen: torch.Generator) -> torch.Tensor:  # [M, 3] -> [M, 4]
    """Frames whose local z is the normal, with a random spin about it (tangent axes vary)."""
    spin = torch.rand(len(normals), generator=gen) * math.pi  # half-angle in [0, π)
    q_spin = torch.stack([spin.cos(), torch.zeros_like(spin), torch.zeros_like(spin), spin.sin()], -1)
    return quat_mul(quat_z_to(normals), q_spin)


def random_unit(m: int, gen: torch.Generator) -> torch.Tensor:  # -> [m, 3]
    """Uniformly random unit vectors."""
    return torch.nn.functional.normalize(torch.randn(m, 3, generator=gen), dim=-1)


def lognormal(m: int, sigma: float, gen: torch.Generator) -> torch.Tensor:  # -> [m]
    """exp(N(0, sigma²)): a positive factor around 1."""
    return torch.exp(sigma * torch.randn(m, generator=gen))


def surface_scales(m: int, h: float, gen: torch.Generator, tangential=0.6, normal=1 / 12) -> torch.Tensor:
    """Flat scales [m, 3]: tangential ≈ tangential·h (two axes), normal ≈ normal·h, log-normal spread."""
    t = tangential * h * lognormal(2 * m, 0.15, gen).reshape(m, 2)
    return torch.cat([t, (normal * h * lognormal(m, 0.2, gen))[:, None]], dim=1)


def rgb_to_sh(rgb: torch.Tensor, degree: int, view_std: float, gen: torch.Generator) -> torch.Tensor:
    """SH [M, (degree+1)², 3]: DC from rgb [M, 3], higher bands N(0, view_std²) (view dependence)."""
    k = (degree + 1) ** 2
    sh = torch.zeros(len(rgb), k, 3)
    sh[:, 0] = (rgb - 0.5) / SH_C0
    if k > 1 and view_std > 0:
        sh[:, 1:] = view_std * torch.randn(len(rgb), k - 1, 3, generator=gen)
    return sh


def opacity_from_logit(mean: float, std: float, m: int, gen: torch.Generator) -> torch.Tensor:
    """Opacities sigmoid(N(mean, std²)) [m]: mostly opaque with natural variation."""
    return torch.sigmoid(mean + std * torch.randn(m, generator=gen))
