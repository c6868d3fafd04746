"""Energy of the simulated state (docs/DESIGN.md "Energy"): kinetic, gravitational and elastic, as float64
device tensors that read nothing back to the host (the tracker records them in its CUDA graph).

    kinetic        Σ ½ m |v|²
    gravitational  Σ m (−g)·(x − x_ref),  x_ref the grid corner lowest along g (every term ≥ 0)
    elastic        Σ V⁰ ψ(F_e)

ψ is each model's strain energy per unit rest volume, written from its textbook form; its derivative
P = ∂ψ/∂F gives the Kirchhoff stress τ = P Fᵀ the kernels (`physics/constitutive.py`) simulate:

    fixed-corotated   μ ‖F − R‖² + λ/2 (J − 1)²                        (R the rotation of F = R S)
    neo-Hookean       μ/2 (tr FᵀF − 3) − μ ln J + λ/2 ln² J
    StVK-Hencky       μ ‖ε‖² + λ/2 (tr ε)²,  ε = ln σ (principal stretches of the elastic F)
    Drucker–Prager    the same Hencky energy of its elastic F

For the two plastic models F_e is the stored F after the plastic return the next substep applies (the
same return, not committed). A band particle whose stress is released after a latch carries no stress,
so no energy (ψ = 0). `drivers_active` says, from the config alone, whether a boundary that drives
motion (a moving cuboid, a particle region) acted in a time window: such a run is not a closed system.
"""

from __future__ import annotations

import math

import torch

from ...config import CuboidBoundary, ParticleRegion, SphereBoundary
from ...linalg import polar_rotation, singular_values
from ...runtime import device_constant
from ..physics.constitutive import MATERIAL_IDS, SIGMA_MIN, lame
from .metrics import kinetic_energy

FIXED_COROTATED, NEO_HOOKEAN, STVK_HENCKY_VM, DRUCKER_PRAGER = (
    MATERIAL_IDS[k] for k in ("fixed_corotated", "neo_hookean", "stvk_hencky_vm", "drucker_prager")
)
J_MIN = 1e-6  # neo-Hookean: the kernel's ln J is taken of max(J, J_MIN); ψ does the same (finite when inverted)


def det3(F: torch.Tensor) -> torch.Tensor:  # [N, 3, 3] -> [N]
    """det F by cofactors: elementwise ops only (no LU, no host sync)."""
    a, b, c = F[:, 0, 0], F[:, 0, 1], F[:, 0, 2]
    d, e, f = F[:, 1, 0], F[:, 1, 1], F[:, 1, 2]
    g, h, i = F[:, 2, 0], F[:, 2, 1], F[:, 2, 2]
    return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)


def hencky_strain(F: torch.Tensor, J: torch.Tensor) -> torch.Tensor:  # -> [N, 3]
    """ε = ln σ of the signed singular values (the smallest carries det F's sign, as the kernels' SVD),
    each stretch clamped to SIGMA_MIN like the kernels (an inverted element stays finite)."""
    s = singular_values(F)  # [N, 3] |σ| descending, float64 Warp kernel
    sign = 1 - 2 * (J < 0).to(s.dtype)  # [N] ±1
    s = torch.cat([s[:, :2], s[:, 2:] * sign[:, None]], 1)
    return torch.log(s.clamp_min(SIGMA_MIN))


def von_mises_elastic(eps, mu, yield_stress):  # [N, 3] -> [N, 3]
    """Radial return of the deviatoric strain onto ‖2μ dev ε‖ ≤ τ_Y (the kernels' von Mises)."""
    dev = eps - eps.mean(1, keepdim=True)
    norm = dev.norm(dim=1, keepdim=True)
    excess = norm - yield_stress[:, None] / (2 * mu[:, None])
    flow = (excess > 0) & (norm > 0)
    return torch.where(flow, eps - dev * excess / norm.clamp_min(1e-300), eps)


def drucker_prager_elastic(eps, mu, lam, alpha):  # [N, 3] -> [N, 3]
    """Return onto the cone ‖dev τ‖ ≤ −α tr τ; tension (tr ε ≥ 0) goes to the tip ε = 0 (the kernels')."""
    tr = eps.sum(1, keepdim=True)
    dev = eps - tr / 3
    norm = dev.norm(dim=1, keepdim=True)
    excess = norm + (3 * lam[:, None] + 2 * mu[:, None]) / (2 * mu[:, None]) * tr * alpha[:, None]
    out = torch.where((excess > 0) & (norm > 0), eps - dev * excess / norm.clamp_min(1e-300), eps)
    return torch.where(tr >= 0, torch.zeros_like(eps), out)


def density(F, material, E, nu, yield_stress=None, alpha=None, models=None, rotation=None) -> torch.Tensor:
    """Strain energy per unit rest volume ψ [J/m³] ([N]) of each particle's F ([N, 3, 3]) for its model
    (`MATERIAL_IDS`), in float64. `models`: the model ids present (known on the host; None: read from `material`, a
    host read), so only their decompositions run: a polar rotation for fixed-corotated, an SVD for the Hencky
    models, nothing for neo-Hookean. `yield_stress` / `alpha` are needed for models 2 / 3. `rotation`: R of F in
    float64 ([N, 3, 3], `polar_rotation(F.double())`) when the caller already has it, else computed here."""
    F = F.double()
    mu, lam = lame(E.double(), nu.double())
    if models is None:
        models = set(material.unique().tolist())
    J = det3(F)
    psi = torch.zeros_like(J)

    def put(model: int, values: torch.Tensor) -> torch.Tensor:  # [N] ψ with `model`'s particles' set to `values`
        """ψ so far with `model`'s particles' entries from `values`: all of `values` when it is the one model."""
        return values if len(models) == 1 else torch.where(material == model, values, psi)

    if FIXED_COROTATED in models:
        R = polar_rotation(F) if rotation is None else rotation  # float64 Warp kernel, the kernels' convention
        psi = put(FIXED_COROTATED, mu * ((F - R) ** 2).sum((1, 2)) + 0.5 * lam * (J - 1) ** 2)
    if NEO_HOOKEAN in models:
        lnJ = torch.log(J.clamp_min(J_MIN))
        psi = put(NEO_HOOKEAN, 0.5 * mu * ((F * F).sum((1, 2)) - 3) - mu * lnJ + 0.5 * lam * lnJ**2)
    if STVK_HENCKY_VM in models or DRUCKER_PRAGER in models:
        eps = hencky_strain(F, J)
        for model, elastic in (
            (STVK_HENCKY_VM, lambda e: von_mises_elastic(e, mu, yield_stress.double())),
            (DRUCKER_PRAGER, lambda e: drucker_prager_elastic(e, mu, lam, alpha.double())),
        ):
            if model in models:
                e = elastic(eps)
                psi = put(model, mu * (e**2).sum(1) + 0.5 * lam * e.sum(1) ** 2)
    return psi


def reference_point(origin, dx: float, shape, gravity) -> tuple:
    """The grid corner lowest along g (largest g·x): the zero of the gravitational energy, so every
    particle inside the grid has E_g ≥ 0 and the total is a positive scale for relative changes."""
    corners = [
        [origin[a] + (shape[a] - 1) * dx * ((k >> a) & 1) for a in range(3)]
        for k in range(8)  # the eight corners of the node box
    ]
    return tuple(max(corners, key=lambda c: sum(g * x for g, x in zip(gravity, c))))


def energies(P, gravity, reference, release: int = 0, models=None, rotation=None) -> torch.Tensor:  # -> [3] [J]
    """(kinetic, gravitational, elastic) of particles `P` as a float64 tensor on their device. `gravity` and
    `reference` are 3-tuples (g [m/s²], the zero of E_g [m]); `release` > 0 zeroes ψ of band particles of
    events 1 … release (their stress is released); `models` and `rotation` as in `density`."""
    dev = P.x.device
    m = P.mass.double()
    kinetic = kinetic_energy(P)
    g = device_constant([float(a) for a in gravity], torch.float64, dev)
    x0 = device_constant([float(a) for a in reference], torch.float64, dev)
    height = (P.x.double() - x0) @ (-g)  # [N] (−g)·(x − x_ref) [m²/s²]
    gravitational = (m * height).sum()
    psi = density(P.F, P.material, P.E, P.nu, P.yield_stress, P.alpha, models, rotation)
    if release > 0:
        psi = torch.where((P.band != 0) & (P.band <= release), torch.zeros_like(psi), psi)
    elastic = (P.volume.double() * psi).sum()
    return torch.stack([kinetic, gravitational, elastic])


def drivers_active(boundaries, t0: float, t1: float, dt: float = 0.0) -> bool:
    """Whether a boundary that drives motion acted in a frame whose substeps start in [t0, t1): a cuboid or a
    sphere with a non-zero velocity (window [start, end]), or a particle region with a non-zero impulse (window
    [start, start + max(end − start, Δt)]) or override velocity (window [start, end + Δt/2]), as
    `boundary.Boundaries.region_table` times them. Static planes, still cuboids and domain walls only
    remove energy."""
    for b in boundaries:
        if isinstance(b, (CuboidBoundary, SphereBoundary)):
            value, end = b.velocity, b.end
        elif isinstance(b, ParticleRegion) and b.kind == "impulse":
            value, end = b.delta_v, b.start + max(b.end - b.start, dt)
        elif isinstance(b, ParticleRegion):
            value, end = b.velocity, b.end + 0.5 * dt
        else:
            continue
        if any(c != 0 for c in value) and b.start < t1 and end >= t0:
            return True
    return False


def relative_change(before: float, after: float) -> float:
    """(after − before) as a fraction of the larger of the two totals (0 when both are 0)."""
    scale = max(abs(before), abs(after))
    return (after - before) / scale if scale > 0 and math.isfinite(scale) else 0.0
