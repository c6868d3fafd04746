"""Constitutive models: Kirchhoff stress τ(F) and plastic return mappings, per particle.

Models (ids in `MATERIAL_IDS`): fixed-corotated (jelly; the paper's scenes), neo-Hookean,
StVK-Hencky with von Mises plasticity and linear hardening (metal), Drucker–Prager (sand,
Klár et al. 2016). Every parameter is per particle. The float64 torch twin of `compute_stress`
is `fracture_gs.sim.reference.stress`; tests compare the two on random inputs.
"""

from __future__ import annotations

import math

import torch
import warp as wp

from ...linalg import polar_newton

wp.set_module_options({"enable_backward": False})  # forward-only kernels compile in half the time

MATERIAL_IDS = {"fixed_corotated": 0, "neo_hookean": 1, "stvk_hencky_vm": 2, "drucker_prager": 3}
SIGMA_MIN = 1e-4  # smallest principal stretch fed to log(): keeps Hencky strain finite under inversion


def lame(E, nu):
    """Lamé parameters (μ, λ) from Young's modulus and Poisson ratio (works on floats and tensors)."""
    return E / (2.0 * (1.0 + nu)), E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))


def dp_alpha(friction_angle_deg):
    """Drucker–Prager cone slope α = √(2/3)·2 sin φ / (3 − sin φ) (floats and tensors)."""
    if torch.is_tensor(friction_angle_deg):
        s = torch.sin(torch.deg2rad(friction_angle_deg))
    else:
        s = math.sin(math.radians(friction_angle_deg))
    return math.sqrt(2.0 / 3.0) * 2.0 * s / (3.0 - s)


@wp.func
def svd3_refined(F: wp.mat33):
    """F = U diag(σ) Vᵀ (U, V rotations). `wp.svd3` runs a fixed number of Jacobi sweeps (residual
    up to ~5e-4 here); a second pass on the nearly diagonal Uᵀ F V brings it to ~1e-6."""
    U, s, V = wp.svd3(F)
    U2, s2, V2 = wp.svd3(wp.transpose(U) * F * V)
    return U * U2, s2, V * V2


@wp.func
def rotation_of(F: wp.mat33):
    """R = U Vᵀ of F = U diag(σ) Vᵀ with U, V rotations (fixed-corotated's R). Where det F > 0 and F is
    not nearly flat it is the polar factor, found by `linalg.polar_newton` (4–5× cheaper than
    `svd3_refined` on the CPU, and ~1e-7 instead of ~1e-6 from a float64 SVD); inverted or nearly flat F
    take the SVD, whose sign convention (σ₃ < 0 for det F < 0) keeps R a rotation."""
    R, converged = polar_newton(F, wp.float32(1e-12))
    if converged != 0:
        return R
    U, sigma, V = svd3_refined(F)
    return U * wp.transpose(V)


@wp.func
def hencky_strain(sigma: wp.vec3):
    """ε = log Σ, with principal stretches clamped to SIGMA_MIN (inverted elements stay finite)."""
    return wp.vec3(
        wp.log(wp.max(sigma[0], SIGMA_MIN)),
        wp.log(wp.max(sigma[1], SIGMA_MIN)),
        wp.log(wp.max(sigma[2], SIGMA_MIN)),
    )


@wp.func
def von_mises_return(eps: wp.vec3, mu: float, yield_stress: float):
    """Radial return of the deviatoric Hencky strain onto ‖2μ ε̂‖ ≤ τ_Y; returns (ε, Δγ ≥ 0)."""
    tr = eps[0] + eps[1] + eps[2]
    dev = eps - wp.vec3(tr / 3.0)
    norm = wp.length(dev)
    dgamma = norm - yield_stress / (2.0 * mu)
    if dgamma <= 0.0 or norm <= 0.0:
        return eps, 0.0
    return eps - dev * (dgamma / norm), dgamma


@wp.func
def drucker_prager_return(eps: wp.vec3, mu: float, lam: float, alpha: float):
    """Return onto the cone ‖dev τ‖ ≤ −α tr τ; tension (tr ε ≥ 0) projects to the tip ε = 0."""
    tr = eps[0] + eps[1] + eps[2]
    if tr >= 0.0:
        return wp.vec3(0.0)
    dev = eps - wp.vec3(tr / 3.0)
    norm = wp.length(dev)
    dgamma = norm + (3.0 * lam + 2.0 * mu) / (2.0 * mu) * tr * alpha
    if dgamma <= 0.0 or norm <= 0.0:
        return eps
    return eps - dev * (dgamma / norm)


@wp.func
def hencky_kirchhoff(U: wp.mat33, eps: wp.vec3, mu: float, lam: float):
    """StVK-Hencky: τ = U diag(2μ ε + λ tr ε) Uᵀ."""
    tr = eps[0] + eps[1] + eps[2]
    d = 2.0 * mu * eps + wp.vec3(lam * tr)
    return U * wp.diag(d) * wp.transpose(U)


@wp.func
def kirchhoff_stress(F: wp.mat33, model: int, mu: float, lam: float):
    """Elastic Kirchhoff stress τ for the hyperelastic models (plasticity already applied to F)."""
    J = wp.determinant(F)
    I = wp.identity(n=3, dtype=float)
    if model == 0:  # fixed-corotated: τ = 2μ(F − R)Fᵀ + λ(J − 1)J I
        R = rotation_of(F)
        return 2.0 * mu * (F - R) * wp.transpose(F) + I * (lam * (J - 1.0) * J)
    if model == 1:  # neo-Hookean: τ = μ(FFᵀ − I) + λ ln J I
        return mu * (F * wp.transpose(F) - I) + I * (lam * wp.log(wp.max(J, 1e-6)))
    U, sigma, V = svd3_refined(F)
    return hencky_kirchhoff(U, hencky_strain(sigma), mu, lam)


@wp.kernel
def compute_stress(
    F: wp.array(dtype=wp.mat33),  # [N] deformation gradient (plastic return written back)
    material: wp.array(dtype=wp.int32),  # [N] MATERIAL_IDS
    E: wp.array(dtype=float),  # [N]
    nu: wp.array(dtype=float),  # [N]
    yield_stress: wp.array(dtype=float),  # [N] von Mises τ_Y (grows with hardening)
    hardening: wp.array(dtype=float),  # [N]
    alpha: wp.array(dtype=float),  # [N] Drucker–Prager cone slope
    band: wp.array(dtype=wp.int32),  # [N] γ_p
    release: int,  # band stress release (Eq. stress_release) for particles banded by events 1 … release (0: off)
    commit: int,  # 1: write the plastic projection back into F (0 for shadow diagnostics)
    stress: wp.array(dtype=wp.mat33),  # [N] out: Kirchhoff stress used by P2G
):
    """Plastic return (models 2, 3), then τ; band particles get (1 − γ_p)τ after the latch (γ_p = the
    1-based index of the event that banded the particle; released up to event `release`)."""
    p = wp.tid()
    Fp = F[p]
    model = material[p]
    mu = E[p] / (2.0 * (1.0 + nu[p]))
    lam = E[p] * nu[p] / ((1.0 + nu[p]) * (1.0 - 2.0 * nu[p]))
    tau = wp.mat33(0.0)
    if model >= 2:
        U, sigma, V = svd3_refined(Fp)
        eps = hencky_strain(sigma)
        if model == 2:
            eps, dgamma = von_mises_return(eps, mu, yield_stress[p])
            if commit != 0 and dgamma > 0.0:
                yield_stress[p] = yield_stress[p] + hardening[p] * 2.0 * mu * dgamma
        else:
            eps = drucker_prager_return(eps, mu, lam, alpha[p])
        Fp = U * wp.diag(wp.vec3(wp.exp(eps[0]), wp.exp(eps[1]), wp.exp(eps[2]))) * wp.transpose(V)
        if commit != 0:
            F[p] = Fp
        tau = hencky_kirchhoff(U, eps, mu, lam)
    else:
        tau = kirchhoff_stress(Fp, model, mu, lam)
    if band[p] != 0 and band[p] <= release:
        tau = wp.mat33(0.0)
    stress[p] = tau
