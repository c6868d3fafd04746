"""Warp's batched 3×3 polar rotation and singular values (fracture_gs.linalg) against their float64
torch twins: R is orthonormal with det R = +1 and equals the SVD polar factor to 1e-5, the singular
values match `svdvals`, and nothing turns NaN for inverted, degenerate, tiny or huge F."""

import pytest
import torch
from torch.testing import assert_close

from fracture_gs.linalg import polar_rotation, polar_rotation_reference, singular_values, singular_values_reference


def hard_cases(n: int, seed: int, dtype) -> torch.Tensor:  # [n, 3, 3]
    g = torch.Generator().manual_seed(seed)
    F = torch.eye(3, dtype=torch.float64) + 0.4 * torch.randn(n, 3, 3, generator=g, dtype=torch.float64)
    k = n // 8
    F[:k] = -F[:k]  # inverted (det < 0)
    F[k : 2 * k] = F[k : 2 * k] @ torch.diag(torch.tensor([1.0, 1.0, 1e-7], dtype=torch.float64))  # nearly flat
    F[2 * k : 3 * k] *= 1e4  # huge
    F[3 * k : 4 * k] *= 1e-4  # tiny
    F[4 * k : 4 * k + 4] = torch.eye(3, dtype=torch.float64)  # identity
    Q, _ = torch.linalg.qr(torch.randn(k, 3, 3, generator=g, dtype=torch.float64))
    F[5 * k : 6 * k] = Q * torch.linalg.det(Q)[:, None, None]  # pure rotations
    return F.to(dtype)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_polar_rotation_matches_the_svd_polar_factor(device, seed, dtype):
    F = hard_cases(4096, seed, dtype)
    # ill-conditioned F (σ₂ ≈ σ₃) has an ill-conditioned polar factor: compare where it is well defined
    s = singular_values_reference(F.double())
    gap = (s[:, 1] + s[:, 2]) / s[:, 0]  # R's sensitivity to F is ~ 1 / (σ_i + σ_j)
    R = polar_rotation(F.to(device)).cpu()
    assert torch.isfinite(R).all()
    eye = torch.eye(3, dtype=torch.float64).expand(len(F), 3, 3)
    tol = 1e-5 if dtype == torch.float32 else 1e-12
    assert_close(R.double().transpose(1, 2) @ R.double(), eye, rtol=0, atol=5 * tol, msg=f"seed {seed}")
    assert_close(torch.linalg.det(R.double()), torch.ones(len(F), dtype=torch.float64), rtol=0, atol=5 * tol)
    well = gap > 1e-3
    ref = polar_rotation_reference(F.double())
    assert_close(R.double()[well], ref[well], rtol=0, atol=tol, msg=f"seed {seed}")


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_singular_values_match_svdvals(device, seed, dtype):
    F = hard_cases(4096, seed, dtype)
    s = singular_values(F.to(device)).cpu().double()
    ref = singular_values_reference(F.double())
    assert (s >= 0).all() and (s[:, :-1] >= s[:, 1:]).all(), "non-negative, descending"
    scale = ref[:, :1]
    tol = 1e-5 if dtype == torch.float32 else 1e-12
    assert_close(s / scale, ref / scale, rtol=0, atol=tol, msg=f"seed {seed}")


def test_shapes_and_empty(device):
    F = torch.eye(3).expand(2, 5, 3, 3).contiguous().to(device)
    assert polar_rotation(F).shape == (2, 5, 3, 3) and singular_values(F).shape == (2, 5, 3)
    assert polar_rotation(torch.empty(0, 3, 3, device=device)).shape == (0, 3, 3)
    with pytest.raises(TypeError):
        polar_rotation(torch.eye(3, dtype=torch.float16))
