"""`deform_covariances` on the CPU (`raster_kernels.deform`, a Warp kernel) against the torch expression it replaces,
½(S + Sᵀ) with S = F Σ⁰ Fᵀ by torch's matmul, bit for bit: float32 and float64, magnitudes from 1e-20 to 1e20 (in
float32 underflow and overflow to inf), signed zeros (a product of zeros is +0 only because the sum starts from +0),
non-contiguous inputs, and no Gaussians at all."""

from __future__ import annotations

import pytest
import torch
from test_render import fresh_seed

from fracture_gs.render.gaussians import deform_covariances


def _torch_expression(F, cov0):
    S = F @ cov0 @ F.transpose(-1, -2)
    return 0.5 * (S + S.transpose(-1, -2))


def _bits(t: torch.Tensor) -> torch.Tensor:
    """The tensor's bit patterns, every NaN made one pattern (the payload of a NaN is not an output)."""
    t = torch.where(torch.isnan(t), torch.full_like(t, float("nan")), t).contiguous()
    return t.view(torch.int32 if t.dtype == torch.float32 else torch.int64)


def _wild(n: int, g, dtype) -> torch.Tensor:  # [n, 3, 3]
    m = torch.randn(n, 3, 3, generator=g, dtype=torch.float64) * 10.0 ** torch.randint(-20, 21, (n, 3, 3), generator=g)
    m[torch.rand(m.shape, generator=g) < 0.15] = 0.0
    m[torch.rand(m.shape, generator=g) < 0.15] = -0.0
    return m.to(dtype)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_cpu_kernel_equals_the_torch_expression_bit_for_bit(dtype):
    seed, g = fresh_seed()
    n = 5000
    for F, cov0 in [
        (_wild(n, g, dtype), _wild(n, g, dtype)),
        (torch.eye(3, dtype=dtype) + 0.3 * torch.randn(n, 3, 3, generator=g).to(dtype), _wild(n, g, dtype)),
        (-torch.zeros(n, 3, 3, dtype=dtype), torch.eye(3, dtype=dtype).expand(n, 3, 3)),  # -0 · x: sums from +0
        (_wild(2 * n, g, dtype)[::2].transpose(1, 2), _wild(n, g, dtype)),  # non-contiguous
    ]:
        got, want = deform_covariances(F, cov0), _torch_expression(F, cov0)
        assert got.dtype == dtype and got.shape == want.shape
        assert torch.equal(_bits(got), _bits(want)), f"seed {seed} {dtype}"
    if dtype == torch.float32:
        assert torch.isinf(_torch_expression(*[_wild(n, g, dtype)] * 2)).any(), "the scene overflows somewhere"
    empty = deform_covariances(torch.zeros(0, 3, 3, dtype=dtype), torch.zeros(0, 3, 3, dtype=dtype))
    assert empty.shape == (0, 3, 3) and empty.dtype == dtype


def test_gradients_and_other_dtypes_take_the_torch_expression():
    """A gradient still flows (the torch path), and float16 is computed as before."""
    F = (torch.eye(3) + 0.1 * torch.randn(4, 3, 3)).requires_grad_()
    cov = deform_covariances(F, torch.eye(3).expand(4, 3, 3))
    cov.sum().backward()
    assert F.grad is not None and F.grad.abs().sum() > 0
    half = torch.eye(3, dtype=torch.bfloat16).expand(2, 3, 3)
    assert torch.equal(deform_covariances(half, half), _torch_expression(half, half))
