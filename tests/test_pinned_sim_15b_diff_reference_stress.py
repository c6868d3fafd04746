"""The float64 twin's Kirchhoff stress of the differentiable path (`sim.diff.reference.stress`) against closed
forms written here from the constitutive laws, not from the code under test.

For F = Q D Vᵀ (Q, V rotations, D = diag(d) the principal stretches, J = d₁d₂d₃) the polar rotation is R = Q Vᵀ,
FFᵀ = Q D² Qᵀ and (F − R)Fᵀ = Q (D − I) D Qᵀ, so

- fixed-corotated (material 0): τ = 2μ Q (D − I) D Qᵀ + λ (J − 1) J I;
- neo-Hookean (material 1):     τ = μ (Q D² Qᵀ − I) + λ ln J I;

both symmetric, both zero for a pure rotation (D = I), and each row scaled by its `released` factor (1 − γ for a
released band particle). Q ≠ V makes F non-symmetric, so a stress built with F instead of Fᵀ is caught."""

import math

import torch

from fracture_gs.sim.diff.reference import stress

MU, LAM = 3.0e4, 2.0e4  # [Pa]


def _rot(axis, angle):
    """Rotation matrix [3, 3] float64 about the unit `axis` by `angle` [rad] (Rodrigues)."""
    a = torch.tensor(axis, dtype=torch.float64)
    a = a / a.norm()
    K = torch.tensor([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]], dtype=torch.float64)
    return torch.eye(3, dtype=torch.float64) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


Q = _rot((1.0, 2.0, 0.5), 0.7)
V = _rot((-0.3, 0.4, 1.0), 1.1)
D = torch.tensor([1.2, 0.85, 1.05], dtype=torch.float64)
J = float(D.prod())
EYE = torch.eye(3, dtype=torch.float64)


def _call(F, material, released=None):
    n = F.shape[0]
    mu = torch.full((n,), MU, dtype=torch.float32)
    lam = torch.full((n,), LAM, dtype=torch.float32)
    rel = torch.ones(n) if released is None else torch.tensor(released)
    return stress(F.float(), torch.tensor(material), mu, lam, rel)


def _fixed_corotated():
    return 2 * MU * Q @ torch.diag((D - 1) * D) @ Q.T + LAM * (J - 1) * J * EYE


def _neo_hookean():
    return MU * (Q @ torch.diag(D * D) @ Q.T - EYE) + LAM * math.log(J) * EYE


def test_fixed_corotated_and_neo_hookean_match_their_closed_forms_for_a_rotated_stretch():
    """A non-symmetric F = Q D Vᵀ: τ of material 0 is 2μ Q(D − I)DQᵀ + λ(J − 1)J I and of material 1
    μ(QD²Qᵀ − I) + λ ln J I, to float32 input precision; both τ are symmetric."""
    F = (Q @ torch.diag(D) @ V.T)[None].expand(2, 3, 3)
    assert float((F[0] - F[0].T).abs().max()) > 0.1  # F is far from symmetric
    tau = _call(F, [0, 1])
    scale = MU  # stresses of order μ; float32 F carries ~1e-7 relative error
    assert float((tau[0] - _fixed_corotated()).abs().max()) < 1e-5 * scale
    assert float((tau[1] - _neo_hookean()).abs().max()) < 1e-5 * scale
    for t in tau:
        assert float((t - t.T).abs().max()) < 1e-6 * scale


def test_a_pure_rotation_carries_no_stress_in_either_model():
    """F = Q (D = I, J = 1): (F − R)Fᵀ = 0 and λ(J − 1)J = 0 for fixed-corotated; FFᵀ − I = 0 and ln 1 = 0 for
    neo-Hookean — a rigid rotation is stress-free."""
    tau = _call(Q[None].expand(2, 3, 3), [0, 1])
    assert float(tau.abs().max()) < 1e-2  # [Pa] against μ = 3e4: round-off of float32 F only


def test_uniaxial_stretch_gives_the_hand_values_on_the_diagonal():
    """F = diag(1.1, 1, 1): fixed-corotated τ₁₁ = 2μ·0.1·1.1 + λ·0.1·1.1 = 8800 Pa, τ₂₂ = τ₃₃ = λ·0.11 = 2200 Pa;
    neo-Hookean τ₁₁ = μ(1.21 − 1) + λ ln 1.1, τ₂₂ = τ₃₃ = λ ln 1.1; no shear."""
    F = torch.diag(torch.tensor([1.1, 1.0, 1.0], dtype=torch.float64))[None].expand(2, 3, 3)
    tau = _call(F, [0, 1])
    fc = torch.diag(torch.tensor([8800.0, 2200.0, 2200.0], dtype=torch.float64))
    ln = math.log(1.1)
    nh = torch.diag(torch.tensor([MU * 0.21 + LAM * ln, LAM * ln, LAM * ln], dtype=torch.float64))
    assert float((tau[0] - fc).abs().max()) < 1e-2
    assert float((tau[1] - nh).abs().max()) < 1e-2


def test_each_row_takes_its_own_model_and_release_factor():
    """Rows pick their model by id and are scaled by `released`: a released band particle (factor 0) carries no
    stress, a partly released one (0.25) a quarter of it, an unbanded one (1) all of it."""
    F = (Q @ torch.diag(D) @ V.T)[None].expand(4, 3, 3)
    tau = _call(F, [1, 0, 0, 1], released=[1.0, 0.25, 0.0, 0.5])
    fc, nh = _fixed_corotated(), _neo_hookean()
    for got, want in ((tau[0], nh), (tau[1], 0.25 * fc), (tau[2], 0 * fc), (tau[3], 0.5 * nh)):
        assert float((got - want).abs().max()) < 1e-5 * MU
    assert float((fc - nh).abs().max()) > 500.0  # the two models differ here (by ~3 % of μ), so the routing is seen
