"""The stress provider's geometry helpers (`sim/providers/stress.py`): the least-variance axis of a point cloud
(the PCA fallback for a crack plane's normal) is the normal of a thin slab wherever the slab sits and however it
is turned (the spread is measured about the points' centroid, not about the origin), and `orient` returns a unit
normal whose largest-magnitude component is positive (a deterministic sign)."""

from __future__ import annotations

import pytest
import torch

from fracture_gs.sim.providers.stress import least_variance_axis, orient


def rotation(g: torch.Generator) -> torch.Tensor:
    """A random proper rotation (QR of a Gaussian matrix, signs fixed)."""
    q, r = torch.linalg.qr(torch.randn(3, 3, generator=g, dtype=torch.float64))
    q = q * torch.sign(torch.diagonal(r))
    return q if torch.det(q) > 0 else -q


@pytest.mark.parametrize("offset", [(0.0, 0.0, 0.0), (5.0, -3.0, 7.0), (0.0, 0.0, 40.0), (-100.0, 2.0, 0.5)])
def test_least_variance_axis_is_the_slab_normal_wherever_the_slab_sits(seed, offset):
    """A slab 0.02 × 0.4 × 0.3 (thin along its own x), turned by a random rotation and moved to `offset` (up to
    100 m from the origin, far more than its size): the returned unit axis is ± the turned x axis to 1e-3."""
    g = torch.Generator().manual_seed(seed)
    R = rotation(g)
    local = (torch.rand(800, 3, generator=g, dtype=torch.float64) - 0.5) * torch.tensor([0.02, 0.4, 0.3])
    x = local @ R.T + torch.tensor(offset, dtype=torch.float64)
    axis = least_variance_axis(x)
    assert float(axis.norm()) == pytest.approx(1.0, abs=1e-12)
    assert abs(float(axis @ R[:, 0])) > 1 - 1e-3, (seed, offset)


def test_least_variance_axis_is_measured_about_the_centroid():
    """A cloud spread 0.5 along z, 0.1 along y and 0.01 along x, centred 3 m out along its thin axis, at (3, 0, 0):
    the axis is ±x (the spread about the centroid), not y (about the origin, its 3 m distance along x would make x
    the largest second moment)."""
    g = torch.Generator().manual_seed(3)
    x = (torch.rand(600, 3, generator=g, dtype=torch.float64) - 0.5) * torch.tensor([0.01, 0.1, 0.5])
    axis = least_variance_axis(x + torch.tensor([3.0, 0.0, 0.0], dtype=torch.float64))
    assert abs(float(axis[0])) > 1 - 1e-4


@pytest.mark.parametrize(
    "n, expected",
    [
        ((0.0, -2.0, 0.0), (0.0, 1.0, 0.0)),
        ((3.0, -4.0, 0.0), (-0.6, 0.8, 0.0)),
        ((-3.0, 4.0, 0.0), (-0.6, 0.8, 0.0)),
        ((0.1, 0.2, -0.9), (-0.1, -0.2, 0.9)),
        ((1.0, 0.0, 0.0), (1.0, 0.0, 0.0)),
    ],
)
def test_orient_gives_a_unit_normal_with_its_largest_component_positive(n, expected):
    """orient(n) = ±n/|n|, the sign chosen so the component of largest magnitude is positive: (3, -4, 0) and
    (-3, 4, 0) both give (-0.6, 0.8, 0); (0.1, 0.2, -0.9) flips (its z is largest) before normalising."""
    got = orient(torch.tensor(n, dtype=torch.float64))
    want = torch.tensor(expected, dtype=torch.float64)
    want = want / want.norm()
    assert torch.allclose(got, want, atol=1e-12), got
