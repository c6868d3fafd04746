"""`sim/energy.py` `energies` on four hand-made particles: kinetic ½ m |v|², gravitational m (−g)·(x − x_ref) and
the elastic V ψ (fixed-corotated, a uniaxial stretch of 1.25: ψ = μ (0.25)² + λ/2 (0.25)², the closed form),
where `release` = r > 0 drops ψ of the band particles of events 1 … r (their stress is released) and the default
(no release) keeps every particle's ψ, band or not."""

import pytest
import torch

from fracture_gs import sim as S
from fracture_gs.sim.diagnostics.energy import energies

YOUNG, NU, VOL, MASS = 2e4, 0.25, 1e-3, 0.5


def _particles():
    x = torch.tensor([[0.0, 0.0, 1.0], [0.5, 0.0, 2.0], [0.0, 1.0, 0.5], [1.0, 1.0, 1.5]])
    v = torch.tensor([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, -3.0], [1.0, 1.0, 1.0]])
    F = torch.diag(torch.tensor([1.25, 1.0, 1.0])).expand(4, 3, 3).contiguous()
    P = S.Particles(
        x=x,
        v=v,
        F=F,
        mass=torch.full((4,), MASS),
        volume=torch.full((4,), VOL),
        E=YOUNG,
        nu=NU,
        material="fixed_corotated",
    )
    P.band = torch.tensor([0, 1, 2, 3], dtype=torch.int32)  # outside any band, then bands of events 1, 2, 3
    return P


def test_energies_are_kinetic_gravitational_and_elastic_with_band_release():
    """Kinetic ½ · 0.5 · (1 + 4 + 9 + 3) = 4.25 J; gravity (0, 0, −9.81) from x_ref at z = 0.5: 0.5 · 9.81 ·
    (0.5 + 1.5 + 0 + 1) J; elastic 4 V ψ with no release (default or 0, or a negative count), 3 V ψ with
    release 1 (event 1's band), 2 V ψ with release 2, V ψ (the particle outside any band) with release 3 or
    more."""
    mu, lam = YOUNG / (2 * (1 + NU)), YOUNG * NU / ((1 + NU) * (1 - 2 * NU))
    psi = mu * 0.25**2 + 0.5 * lam * 0.25**2
    P, g, ref = _particles(), (0.0, 0.0, -9.81), (0.0, 0.0, 0.5)
    kin, grav, el = energies(P, g, ref).tolist()
    assert kin == pytest.approx(4.25, rel=1e-12)
    assert grav == pytest.approx(MASS * 9.81 * 3.0, rel=1e-6)
    assert el == pytest.approx(4 * VOL * psi, rel=1e-5)
    for release, kept in ((0, 4), (-1, 4), (1, 3), (2, 2), (3, 1), (99, 1)):
        out = energies(P, g, ref, release).tolist()
        assert out[2] == pytest.approx(kept * VOL * psi, rel=1e-5), release
        assert out[:2] == [kin, grav], release
