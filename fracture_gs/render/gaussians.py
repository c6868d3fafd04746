"""Per-frame Gaussian update from the deformation gradient (DESIGN.md "Rendering").

A particle that came from a Gaussian carries its rest covariance Σ⁰ = R S Sᵀ Rᵀ and its SH
coefficients, expressed in the rest frame. After deformation by F:

    mean  = x_p,                 Σ = F Σ⁰ Fᵀ                      (affine push-forward)
    F = R U (polar),             colour(d) = SH(Rᵀ d)              (view direction into rest frame)

The SH rotation is done by rotating the *view direction* instead of the coefficients: evaluating
the rest-frame SH at Rᵀd is exactly the SH of the rotated signal at d, for every degree.
Takes tensors only; never imports `fracture_gs.sim`.
"""

from __future__ import annotations

import torch
from torch import Tensor

from ..errors import RenderError
from ..linalg import polar_rotation  # noqa: F401  (re-exported: R(F) for the SH rotation)
from ..sh import SH_C0, SH_C1, SH_C2, SH_C3


def deform_covariances(F: Tensor, cov0: Tensor) -> Tensor:  # [N,3,3], [N,3,3] -> [N,3,3]
    """Σ = F Σ⁰ Fᵀ, symmetrized so the result is exactly symmetric (SPD when det F ≠ 0). On the CPU (float32 or
    float64, no gradient) a Warp kernel computes the torch expression's very bits (`raster_kernels.deform`)."""
    for name, t in (("F", F), ("cov0", cov0)):
        if not isinstance(t, Tensor) or t.ndim != 3 or tuple(t.shape[1:]) != (3, 3):
            what = f"shape {list(t.shape)}" if isinstance(t, Tensor) else f"type {type(t).__name__}"
            raise RenderError(
                f"deform_covariances: {name} has {what}, not [N, 3, 3]; pass one 3×3 matrix per Gaussian."
            )
    if F.shape[0] != cov0.shape[0]:
        raise RenderError(
            f"deform_covariances: F has {F.shape[0]} matrices but cov0 {cov0.shape[0]}; pass one of each per Gaussian."
        )
    grad = torch.is_grad_enabled() and (F.requires_grad or cov0.requires_grad)
    on_cpu = F.device.type == "cpu" and cov0.device.type == "cpu"
    if on_cpu and F.dtype in (torch.float32, torch.float64) and cov0.dtype == F.dtype and not grad:
        from .raster_kernels import deform  # lazy: Warp's CPU render kernels load with the first CPU frame

        return deform(F, cov0)  # the same bits as below, a few times faster
    S = F @ cov0 @ F.transpose(-1, -2)
    return 0.5 * (S + S.transpose(-1, -2))


def limit_stretch(F: Tensor, s_max: float) -> Tensor:  # [N,3,3] -> [N,3,3]
    """F with its principal stretches σ clamped to [1/s_max, s_max]: with F = U Σ Vᵀ, U Σ_c Vᵀ = F V diag(Σ_c/Σ) Vᵀ
    (same rotation R = U Vᵀ, so SH colours do not change). Only rows with ‖FᵀF − I‖_F above the band are
    decomposed (eigh of FᵀF in float64); the rest are returned as they are."""
    C = F.transpose(-1, -2) @ F  # [N,3,3] = V Σ² Vᵀ
    eye = torch.eye(3, dtype=F.dtype, device=F.device)
    band = min(s_max**2 - 1.0, 1.0 - 1.0 / s_max**2)
    rows = torch.nonzero(torch.linalg.matrix_norm(C - eye) > band).flatten()
    if len(rows) == 0:
        return F
    from ..linalg import eigh_chunked

    lam, V = eigh_chunked(C[rows].double())
    sigma = lam.clamp_min(1e-30).sqrt()
    ratio = sigma.clamp(1.0 / s_max, s_max) / sigma  # [R,3]
    out = F.clone()
    out[rows] = (F[rows].double() @ (V * ratio[:, None, :]) @ V.transpose(-1, -2)).to(F.dtype)
    return out


def sh_basis(dirs: Tensor, degree: int) -> Tensor:  # [N,3] unit -> [N,(degree+1)²]
    """Real SH basis of degree 0–3 at unit directions, in the 3DGS ordering and sign convention."""
    if not 0 <= degree <= 3:
        raise ValueError(f"SH degree must be 0..3, got {degree}")
    x, y, z = dirs.unbind(-1)
    out = [torch.full_like(x, SH_C0)]
    if degree >= 1:
        out += [-SH_C1 * y, SH_C1 * z, -SH_C1 * x]
    if degree >= 2:
        xx, yy, zz, xy, yz, xz = x * x, y * y, z * z, x * y, y * z, x * z
        out += [SH_C2[0] * xy, SH_C2[1] * yz, SH_C2[2] * (2 * zz - xx - yy), SH_C2[3] * xz, SH_C2[4] * (xx - yy)]
    if degree >= 3:
        out += [
            SH_C3[0] * y * (3 * xx - yy),
            SH_C3[1] * xy * z,
            SH_C3[2] * y * (4 * zz - xx - yy),
            SH_C3[3] * z * (2 * zz - 3 * xx - 3 * yy),
            SH_C3[4] * x * (4 * zz - xx - yy),
            SH_C3[5] * z * (xx - yy),
            SH_C3[6] * x * (xx - 3 * yy),
        ]
    return torch.stack(out, dim=-1)


def sh_colors(
    sh: Tensor,  # [N, K, 3] SH coefficients in the rest frame, K = (deg+1)², DC first
    means: Tensor,  # [N, 3] current (deformed) world positions
    campos: Tensor,  # [3] camera centre in world coordinates
    R: Tensor | None = None,  # [N, 3, 3] polar rotation of F, or None (no rotation)
) -> Tensor:  # [N, 3] RGB, ≥ 0
    """colour = max(0, Σ_lm c_lm Y_lm(d_rest) + 0.5) with d_rest = Rᵀ (x − c)/|x − c|."""
    K = sh.shape[-2]
    degree = int(round(K**0.5)) - 1
    if (degree + 1) ** 2 != K or degree > 3:
        raise RenderError(
            f"sh_colors: sh has K = {K} coefficients per channel; pass [N, (degree+1)², 3] with degree 0 to 3 (K = 1, "
            "4, 9 or 16)."
        )
    d = means - campos.to(means)[None, :]
    d = d / d.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    if R is not None and degree > 0:  # degree 0 is view-independent
        d = torch.einsum("nji,nj->ni", R.to(d), d)  # Rᵀ d
    basis = sh_basis(d, degree)  # [N, K]
    rgb = torch.einsum("nk,nkc->nc", basis.to(sh.dtype), sh) + 0.5
    return rgb.clamp_min(0.0)


def exposed_interior_colors(
    interior_means: Tensor,  # [N, 3] interior fill particles to colour
    surface_means: Tensor,  # [M, 3] surface Gaussians
    surface_colors: Tensor,  # [M, C] their colours
    chunk: int = 4096,
) -> Tensor:  # [N, C]
    """Colour of the nearest surface Gaussian, found by chunked `cdist` (memory ≤ chunk² floats)."""
    n, m = interior_means.shape[0], surface_means.shape[0]
    if m == 0:
        raise ValueError("exposed_interior_colors: no surface Gaussians to take colours from")
    best_d = torch.full((n,), float("inf"), dtype=interior_means.dtype, device=interior_means.device)
    best_i = torch.zeros(n, dtype=torch.long, device=interior_means.device)
    for i0 in range(0, n, chunk):
        q = interior_means[i0 : i0 + chunk]
        bd, bi = best_d[i0 : i0 + chunk], best_i[i0 : i0 + chunk]
        for j0 in range(0, m, chunk):
            dmin, jmin = torch.cdist(q, surface_means[j0 : j0 + chunk]).min(dim=1)
            better = dmin < bd
            bd = torch.where(better, dmin, bd)
            bi = torch.where(better, jmin + j0, bi)
        best_d[i0 : i0 + chunk], best_i[i0 : i0 + chunk] = bd, bi
    return surface_colors[best_i]


def visible_mask(
    interior: Tensor,  # [N] bool: interior fill particle
    exposed: Tensor,  # [N] bool: exposed by a fracture
    show_exposed: bool,
) -> Tensor:  # [N] bool
    """Surface Gaussians always; interior ones only when exposed and `show_exposed`."""
    interior = interior.bool()
    if not show_exposed:
        return ~interior
    return ~interior | exposed.bool()
