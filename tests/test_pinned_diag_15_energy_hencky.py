"""The energy diagnostics' Hencky strain and return maps (`sim.diagnostics.energy`) against hand values.

- `hencky_strain`: ε = ln σ of the signed principal stretches — for det F < 0 the smallest stretch is negative and
  is clamped to SIGMA_MIN = 1e-4 (the kernels' convention, an inverted element stays finite); for det F > 0 it is
  its own log. Rotations on either side change nothing.
- `von_mises_elastic`: the deviatoric part of ε is scaled back onto ‖2μ dev ε‖ = τ_Y when beyond it, the volumetric
  part kept; inside it ε is unchanged.
- `drucker_prager_elastic`: tension (tr ε ≥ 0) returns to ε = 0; in compression a strain outside the cone is moved
  onto ‖dev ε‖ = (3λ + 2μ)/(2μ)·α·|tr ε| along its own deviator, keeping tr ε; inside the cone it is unchanged.
- `density` of an inverted element: fixed-corotated μ Σ(σᵢ − 1)² + λ/2 (J − 1)² with the signed σ; Hencky models
  with ε₃ = ln 1e-4."""

import math

import pytest
import torch

from fracture_gs.sim.diagnostics.energy import density, drucker_prager_elastic, hencky_strain, von_mises_elastic

LN_MIN = math.log(1e-4)  # the clamp written by hand, not imported


def _rot(angle, axis):
    a = torch.tensor(axis, dtype=torch.float64)
    a = a / a.norm()
    K = torch.tensor([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]], dtype=torch.float64)
    return torch.eye(3, dtype=torch.float64) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def _F(stretches):
    """Q diag(stretches) Vᵀ [1, 3, 3] for two fixed rotations Q, V."""
    return (
        _rot(0.8, (1.0, 2.0, 3.0))
        @ torch.diag(torch.tensor(stretches, dtype=torch.float64))
        @ _rot(-0.5, (0.0, 1.0, -1.0)).T
    )[None]


def test_the_hencky_strain_of_an_inverted_element_clamps_its_negative_stretch():
    """Stretches (2, 1.5, −0.5), det F = −1.5: ε = (ln 2, ln 1.5, ln 1e-4); stretches (2, 1.5, 0.5): (ln 2, ln 1.5,
    ln 0.5); stretches (0.25, 1, 3) upright: ε sorted with the stretches, descending (ln 3, 0, ln 0.25)."""
    for s, want in (
        ((2.0, 1.5, -0.5), (math.log(2.0), math.log(1.5), LN_MIN)),
        ((2.0, 1.5, 0.5), (math.log(2.0), math.log(1.5), math.log(0.5))),
        ((0.25, 1.0, 3.0), (math.log(3.0), 0.0, math.log(0.25))),
    ):
        F = _F(s)
        eps = hencky_strain(F, torch.det(F))
        assert eps[0].tolist() == pytest.approx(want, abs=1e-9), s


def test_von_mises_scales_the_deviator_back_to_the_yield_surface():
    """ε = (0.13, 0.03, −0.07): tr = 0.09, dev = (0.1, 0, −0.1), ‖dev‖ = 0.1√2. With μ = 1e4 and τ_Y = 2μ·0.05√2 the
    deviator is halved: (0.08, 0.03, −0.02); with τ_Y twice the trial stress ε is unchanged."""
    eps = torch.tensor([[0.13, 0.03, -0.07]], dtype=torch.float64)
    mu = torch.tensor([1e4], dtype=torch.float64)
    out = von_mises_elastic(eps, mu, torch.tensor([2e4 * 0.05 * math.sqrt(2)], dtype=torch.float64))
    assert out[0].tolist() == pytest.approx([0.08, 0.03, -0.02], abs=1e-12)
    same = von_mises_elastic(eps, mu, torch.tensor([4e4 * 0.1 * math.sqrt(2)], dtype=torch.float64))
    assert torch.equal(same, eps)


def test_drucker_prager_returns_tension_to_zero_and_compression_onto_the_cone():
    """μ = λ (factor (3λ + 2μ)/(2μ) = 2.5). ε = (−0.1, −0.1, −0.4): tr = −0.6, dev = (0.1, 0.1, −0.2). α = 0.1:
    the cone allows ‖dev‖ = 2.5·0.1·0.6 = 0.15 < √0.06, so the result keeps tr = −0.6 and has a deviator of norm 0.15
    along dev; α = 0.5 allows 0.75: unchanged. ε = (0.05, 0, −0.02) and (0.02, −0.005, −0.01) (tr = 0.03, 0.005):
    0. A trace of exactly 0: 0."""
    mu = lam = torch.tensor([1e4], dtype=torch.float64)
    eps = torch.tensor([[-0.1, -0.1, -0.4]], dtype=torch.float64)
    dev = torch.tensor([0.1, 0.1, -0.2], dtype=torch.float64)
    out = drucker_prager_elastic(eps, mu, lam, torch.tensor([0.1], dtype=torch.float64))[0]
    want = -0.2 + dev * 0.15 / math.sqrt(0.06)
    assert out.tolist() == pytest.approx(want.tolist(), abs=1e-12)
    inside = drucker_prager_elastic(eps, mu, lam, torch.tensor([0.5], dtype=torch.float64))
    assert torch.equal(inside, eps)
    for tension in ([0.05, 0.0, -0.02], [0.02, -0.005, -0.01], [0.1, -0.05, -0.05]):
        zero = drucker_prager_elastic(torch.tensor([tension], dtype=torch.float64), mu, lam, torch.tensor([0.5]))
        assert zero.abs().max() == 0, tension


def test_the_energy_of_an_inverted_element_by_model():
    """Stretches (2, 1.5, −0.5), E = 1e5, ν = 0.25 (μ = λ = 4e4 Pa): fixed-corotated ψ = μ(1 + 0.25 + 2.25) +
    λ/2·(−2.5)² = 265000 J/m³; stvk_hencky_vm without yielding ψ = μ Σε² + λ/2 (Σε)² with ε₃ = ln 1e-4."""
    F = _F((2.0, 1.5, -0.5)).expand(2, 3, 3)
    one = torch.ones(2, dtype=torch.float64)
    mat = torch.tensor([0, 2], dtype=torch.int32)
    psi = density(F, mat, 1e5 * one, 0.25 * one, 1e30 * one, 0.0 * one)
    assert float(psi[0]) == pytest.approx(265000.0, rel=1e-9)
    e = torch.tensor([math.log(2.0), math.log(1.5), LN_MIN], dtype=torch.float64)
    assert float(psi[1]) == pytest.approx(float(4e4 * (e**2).sum() + 2e4 * e.sum() ** 2), rel=1e-9)
