"""Hand-written bug campaign, round two: the plastic return's bookkeeping (`sim.physics.constitutive`).

Von Mises with linear hardening H on an isochoric stretch F = diag(s, 1/s, 1): the Hencky strain is
ε = (ln s, −ln s, 0), all deviatoric, ‖dev ε‖ = √2 ln s. Beyond the yield radius τ_Y/2μ the return projects it
onto that radius, Δγ = √2 ln s − τ_Y/2μ, and a committed return raises τ_Y by H·2μ·Δγ. The diagnostics' shadow
stress (commit = 0) computes the same τ but writes neither F nor τ_Y: a diagnostic must not change the run.
"""

import math

import torch
from simutil import config

from fracture_gs import sim as S

E, NU, TAU_Y, H, STRETCH = 1e6, 0.3, 2e4, 0.5, 1.1


def _metal(n=8):
    """n von Mises particles in the middle of a 32³ grid, each with F = diag(1.1, 1/1.1, 1)."""
    x = 0.5 + 0.01 * torch.arange(n, dtype=torch.float32)[:, None].repeat(1, 3)
    F = torch.diag(torch.tensor([STRETCH, 1 / STRETCH, 1.0])).repeat(n, 1, 1)
    P = S.Particles(x=x, mass=torch.full((n,), 1e-3), volume=torch.full((n,), 1e-6), F=F, E=E, nu=NU,
                    material="stvk_hencky_vm", yield_stress=TAU_Y, hardening=H)  # fmt: skip
    return S.Simulator(config(32), P, device="cpu")


def test_a_shadow_stress_leaves_f_and_the_yield_stress_and_a_committed_one_hardens_by_hand():
    """commit = 0: F and τ_Y stay as they were (bit for bit); commit = 1 gives the same τ, F's deviatoric stretch at
    the yield radius (ln σ₁ = τ_Y/2μ/√2) and τ_Y + H·2μ·Δγ."""
    sim = _metal()
    P = sim.particles
    F0, y0 = P.F.clone(), P.yield_stress.clone()
    shadow = torch.zeros_like(sim.stress)
    sim.compute_stress(shadow, commit=False)
    assert torch.equal(P.F, F0), "a shadow stress wrote the plastic return into F"
    assert torch.equal(P.yield_stress, y0), "a shadow stress hardened the particles"
    committed = torch.zeros_like(sim.stress)
    sim.compute_stress(committed, commit=True)
    assert torch.allclose(committed, shadow, rtol=1e-5, atol=1e-3), "commit changes τ of this substep"
    mu = E / (2 * (1 + NU))
    radius = TAU_Y / (2 * mu)
    dgamma = math.sqrt(2) * math.log(STRETCH) - radius
    expected = TAU_Y + H * 2 * mu * dgamma
    assert P.yield_stress.double().sub(expected).abs().max() <= 1e-4 * expected
    ln_s1 = torch.log(torch.linalg.svdvals(P.F.double())[:, 0])
    assert ln_s1.sub(radius / math.sqrt(2)).abs().max() <= 1e-5
