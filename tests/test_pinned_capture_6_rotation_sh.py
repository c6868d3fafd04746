"""Pinned rules of the rotation helpers of `capture.transform`, round six:

- the SH fit's sample directions (`_sample_dirs`) are a Fibonacci sphere: n unit vectors with z evenly spaced at
  1 − (2i + 1)/n and each azimuth a golden angle π(3 − √5) past the previous one;
- `rotate_sh` is exact (to round-off) for every SH degree 1–3, with one rotation for all Gaussians or one per
  Gaussian, across chunk boundaries: the rotated coefficients evaluated at d equal the original evaluated at Rᵀd;
- `quat_from_matrix` returns the unit quaternion (w ≥ 0) of a rotation for every one of Shepperd's four
  branches (identity-like, and half-turns about x, y and z, where w vanishes), checked against the textbook
  quaternion-to-matrix formula written out here, and a 90° turn about z is (cos 45°, 0, 0, sin 45°).
"""

from __future__ import annotations

import math

import pytest
import torch

from fracture_gs.capture.transform import _sample_dirs, quat_from_matrix, rotate_sh
from fracture_gs.render.gaussians import sh_basis

pytestmark = pytest.mark.usefixtures("one_thread")

F64 = torch.float64


def rotation(axis, angle: float) -> torch.Tensor:  # [3, 3], Rodrigues' formula written out
    k = torch.tensor(axis, dtype=F64)
    k = k / k.norm()
    K = torch.tensor([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]], dtype=F64)
    return torch.eye(3, dtype=F64) + math.sin(angle) * K + (1 - math.cos(angle)) * (K @ K)


def matrix_of(q: torch.Tensor) -> torch.Tensor:  # [..., 4] wxyz -> [..., 3, 3], the textbook formula
    w, x, y, z = q.unbind(-1)
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]
    return torch.stack([torch.stack(r, -1) for r in rows], -2)


def random_rotations(n: int, seed: int) -> torch.Tensor:  # [n, 3, 3], proper
    g = torch.Generator().manual_seed(seed)
    Q, _ = torch.linalg.qr(torch.randn(n, 3, 3, generator=g, dtype=F64))
    Q[torch.linalg.det(Q) < 0, :, 0] *= -1
    return Q


@pytest.mark.parametrize("n", [64, 10])
def test_the_sample_directions_are_a_fibonacci_sphere(n):
    """n unit vectors; z_i = 1 − (2i + 1)/n exactly; consecutive azimuths differ by the golden angle π(3 − √5)
    (mod 2π), so no two directions coincide and they cover the sphere."""
    d = _sample_dirs(n)
    assert d.shape == (n, 3) and d.dtype == F64
    assert torch.allclose(d.norm(dim=1), torch.ones(n, dtype=F64), atol=1e-14, rtol=0)
    i = torch.arange(n, dtype=F64)
    assert torch.allclose(d[:, 2], 1 - (2 * i + 1) / n, atol=1e-15, rtol=0)
    step = torch.atan2(d[1:, 1], d[1:, 0]) - torch.atan2(d[:-1, 1], d[:-1, 0])
    off = torch.remainder(step - math.pi * (3 - math.sqrt(5)) + math.pi, 2 * math.pi) - math.pi
    assert float(off.abs().max()) < 1e-12
    assert float(torch.cdist(d, d).add(torch.eye(n, dtype=F64) * 9).min()) > 0.1


@pytest.mark.parametrize("degree", [1, 2, 3])
@pytest.mark.parametrize("per_gaussian", [False, True])
def test_rotated_sh_evaluated_at_d_is_the_original_at_r_transpose_d(degree, per_gaussian):
    """For 7 Gaussians with random coefficients (float64), one rotation for all or one each, in chunks of 3 (so
    the last chunk is short): Σ c'_k Y_k(d) = Σ c_k Y_k(Rᵀd) on 300 random directions, to 1e-13."""
    K = (degree + 1) ** 2
    g = torch.Generator().manual_seed(degree)
    sh = torch.randn(7, K, 3, generator=g, dtype=F64)
    R = random_rotations(7, 11 + degree) if per_gaussian else random_rotations(1, 11 + degree)[0]
    out = rotate_sh(sh, R, chunk=3)
    d = torch.randn(300, 3, generator=g, dtype=F64)
    d = d / d.norm(dim=1, keepdim=True)
    Rs = R if per_gaussian else R.expand(7, 3, 3)
    for n in range(7):
        lhs = sh_basis(d, degree) @ out[n]  # [300, 3]
        rhs = sh_basis(d @ Rs[n], degree) @ sh[n]  # (d @ R)_i = (Rᵀ d)_i
        assert float((lhs - rhs).abs().max()) < 1e-13, n
    assert not torch.allclose(out, sh), "a real rotation changes the coefficients"


def test_degree_zero_and_empty_sets_come_back_as_copies():
    """Degree 0 (colour only) is rotation-invariant: the coefficients come back equal, as a new tensor (changing
    it leaves the input alone); an empty set of degree 3 comes back empty with the same shape."""
    R = rotation((1.0, 2.0, 3.0), 0.7)
    sh = torch.randn(4, 1, 3, dtype=F64)
    out = rotate_sh(sh, R)
    assert torch.equal(out, sh)
    out += 1.0
    assert not torch.equal(out, sh), "the result is a copy, not the input"
    empty = rotate_sh(torch.zeros(0, 16, 3, dtype=F64), R)
    assert empty.shape == (0, 16, 3) and empty.dtype == F64


@pytest.mark.parametrize(
    "axis, angle",
    [
        ((0.0, 0.0, 1.0), 0.0),  # identity: w is the largest candidate
        ((1.0, 0.0, 0.0), math.pi),  # half-turns: w = 0, x, y or z the largest
        ((0.0, 1.0, 0.0), math.pi),
        ((0.0, 0.0, 1.0), math.pi),
        ((1.0, 1.0, 0.0), math.pi),
        ((0.2, -0.5, 1.0), 0.999 * math.pi),
        ((-1.0, 0.3, 0.1), 2.5),
        ((0.3, 1.0, -0.4), 3.0),
        ((0.1, 0.2, -1.0), 3.1),
        ((1.0, -2.0, 0.5), 0.4),
    ],
)
def test_the_quaternion_of_a_rotation_rebuilds_it(axis, angle):
    """Shepperd's method picks the largest of four candidates; whichever it picks, the unit quaternion it returns
    (w ≥ 0) rebuilds the rotation by the textbook formula to 1e-12, and is ±(cos θ/2, sin θ/2 · axis)."""
    R = rotation(axis, angle)
    q = quat_from_matrix(R)
    assert q.shape == (4,) and float(q[0]) >= 0 and abs(float(q.norm()) - 1) < 1e-14
    assert torch.allclose(matrix_of(q), R, atol=1e-12, rtol=0)
    k = torch.tensor(axis, dtype=F64) / torch.tensor(axis, dtype=F64).norm()
    want = torch.cat([torch.tensor([math.cos(angle / 2)], dtype=F64), math.sin(angle / 2) * k])
    assert torch.allclose(q, want, atol=1e-12) or torch.allclose(q, -want, atol=1e-12)


def test_a_quarter_turn_about_z_and_a_batch():
    """A 90° turn about z is (cos 45°, 0, 0, sin 45°); a [2, 5, 3, 3] batch of random rotations gives a
    [2, 5, 4] batch, each rebuilding its own rotation, with w ≥ 0."""
    q = quat_from_matrix(rotation((0.0, 0.0, 1.0), math.pi / 2))
    assert torch.allclose(q, torch.tensor([math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)], dtype=F64), atol=1e-15)
    R = random_rotations(10, 2).reshape(2, 5, 3, 3)
    q = quat_from_matrix(R)
    assert q.shape == (2, 5, 4) and bool((q[..., 0] >= 0).all())
    assert torch.allclose(matrix_of(q), R, atol=1e-12, rtol=0)
