"""`GaussianSet`: a 3D Gaussian scene as torch tensors (the type io, assets and users share)."""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Optional

import torch


@dataclass
class GaussianSet:
    """N Gaussians with activated parameters (what a renderer consumes).

    A 3DGS PLY stores log-scales and logit-opacities; `fracture_gs.io.load_ply` activates them
    (exp, sigmoid) and `save_ply` inverts that. Interior fill particles are Gaussians too: they
    are simulated but not drawn unless a fracture exposes them (`interior`).
    """

    means: torch.Tensor  # [N, 3] world positions
    quats: torch.Tensor  # [N, 4] unit quaternions, wxyz
    scales: torch.Tensor  # [N, 3] standard deviations along the local axes (> 0)
    opacities: torch.Tensor  # [N] in (0, 1)
    sh: torch.Tensor  # [N, K, 3] SH coefficients, K = (degree+1)², DC first
    interior: Optional[torch.Tensor] = None  # [N] bool: interior fill particle (not drawn by default)
    labels: Optional[torch.Tensor] = None  # [N] int32 material label (material maps)
    extra: dict = field(default_factory=dict)  # name -> [N] tensor: other per-Gaussian properties
    carrier: Optional[Carrier] = None  # simulate carrier.particles, these Gaussians follow them (None: 1:1)

    def __post_init__(self):
        n = self.means.shape[0]
        if self.interior is None:
            self.interior = torch.zeros(n, dtype=torch.bool, device=self.means.device)
        if self.labels is None:
            self.labels = torch.zeros(n, dtype=torch.int32, device=self.means.device)

    def __len__(self) -> int:
        return self.means.shape[0]

    @property
    def sh_degree(self) -> int:
        return int(round(self.sh.shape[1] ** 0.5)) - 1

    @property
    def device(self) -> torch.device:
        return self.means.device

    def to(self, device) -> GaussianSet:
        moved = {f.name: getattr(self, f.name) for f in fields(self) if f.name not in ("extra", "carrier")}
        moved = {k: v.to(device) if torch.is_tensor(v) else v for k, v in moved.items()}
        carrier = self.carrier.to(device) if self.carrier is not None else None
        return GaussianSet(**moved, extra={k: v.to(device) for k, v in self.extra.items()}, carrier=carrier)

    def subset(self, mask: torch.Tensor) -> GaussianSet:
        """The Gaussians selected by a boolean mask or index tensor (without a carrier: its map is per Gaussian)."""
        pick = {f.name: getattr(self, f.name)[mask] for f in fields(self) if f.name not in ("extra", "carrier")}
        return GaussianSet(**pick, extra={k: v[mask] for k, v in self.extra.items()})

    def rotations(self) -> torch.Tensor:  # [N, 3, 3]
        """Rotation matrices of the (normalized) wxyz quaternions."""
        return quat_to_matrix(self.quats)

    def covariances(self) -> torch.Tensor:  # [N, 3, 3]
        """Rest covariances Σ⁰ = R S Sᵀ Rᵀ."""
        M = self.rotations() * self.scales[:, None, :]
        return M @ M.transpose(1, 2)

    def replace(self, **changes) -> GaussianSet:
        return replace(self, **changes)


def quat_to_matrix(q: torch.Tensor) -> torch.Tensor:  # [N, 4] wxyz (any norm) -> [N, 3, 3]
    """Rotation matrices of wxyz quaternions (normalized first)."""
    w, x, y, z = torch.nn.functional.normalize(q, dim=-1).unbind(-1)
    return torch.stack(
        [
            1 - 2 * (y * y + z * z),
            2 * (x * y - w * z),
            2 * (x * z + w * y),
            2 * (x * y + w * z),
            1 - 2 * (x * x + z * z),
            2 * (y * z - w * x),
            2 * (x * z - w * y),
            2 * (y * z + w * x),
            1 - 2 * (x * x + y * y),
        ],
        dim=-1,
    ).reshape(-1, 3, 3)


def quat_mul(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:  # [M, 4] × [M, 4] -> [M, 4]
    """Hamilton product of wxyz quaternions."""
    aw, ax, ay, az = a.unbind(-1)
    bw, bx, by, bz = b.unbind(-1)
    return torch.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        dim=-1,
    )


@dataclass
class Carrier:
    """Fewer simulated particles than drawn Gaussians: the simulation runs on `particles`, and Gaussian g is
    carried by particle a = index[g] with that particle's affine motion, x_g = x_a + F_a (x⁰_g − x⁰_a) and
    F_g = F_a (so Σ_g = F_a Σ⁰_g F_aᵀ), together with its fragment and band. Built by `capture.sample`."""

    particles: GaussianSet  # [P] the simulated set (interior fill included)
    index: torch.Tensor  # [G] int64: the carrying particle of each Gaussian
    offset: torch.Tensor  # [G, 3] x⁰_g − x⁰_a [m]

    def to(self, device) -> Carrier:
        return Carrier(self.particles.to(device), self.index.to(device), self.offset.to(device))

    def reordered(self, order: torch.Tensor) -> Carrier:
        """The same carrier with its particles permuted to `particles[order]` (e.g. into grid-cell order)."""
        position = torch.empty_like(order)
        position[order] = torch.arange(len(order), device=order.device)
        return Carrier(self.particles.subset(order), position[self.index], self.offset)

    def carry(self, x: torch.Tensor, F: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Particle positions [P, 3] and deformation gradients [P, 3, 3] → each Gaussian's ([G, 3], [G, 3, 3])."""
        Fg = F.index_select(0, self.index)
        means = x.index_select(0, self.index) + (Fg @ self.offset.to(F.dtype)[:, :, None])[:, :, 0]
        return means, Fg
