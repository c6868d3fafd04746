"""The surface measure's depth inversion in Warp (`penetration_kernels.depth_from_share`) against its torch twin
(`penetration.depth_from_fraction`) and against the closed form it inverts: for every share c in [0, 1] it returns
the u in [−1, 1] with F(u) = c, F the kernel's half-space share, to the bisection's 2⁻⁴⁰; shares outside [0, 1]
read as the nearest end (a piece cannot fill less than none or more than all of the ball)."""

import torch

from fracture_gs.sim.diagnostics.penetration import depth_from_fraction, fraction_of_half_space
from fracture_gs.sim.diagnostics.penetration_kernels import depth_from_share


def test_the_kernel_inverts_the_half_space_share():
    """u → F(u) → depth_from_share gives u back within 1e-11 for |u| ≤ 0.95; towards the ends F flattens (F′ ∝ (1 − u²)²,
    so a share one rounding from 1 is a cube root of it, ≈ 1e-5, from u = 1) and u comes back within 1e-4. F of the
    returned u is the share asked for everywhere."""
    u = torch.linspace(-1, 1, 4001, dtype=torch.float64)
    back = depth_from_share(fraction_of_half_space(u))
    inner = u.abs() <= 0.95
    torch.testing.assert_close(back[inner], u[inner], rtol=0, atol=1e-11)
    torch.testing.assert_close(back, u, rtol=0, atol=1e-4)
    c = torch.rand(5000, dtype=torch.float64, generator=torch.Generator().manual_seed(4))
    torch.testing.assert_close(fraction_of_half_space(depth_from_share(c)), c, rtol=0, atol=1e-11)


def test_the_kernel_matches_its_torch_twin():
    """Same bisection, same polynomial: the Warp kernel and the torch twin agree to 1e-12 on random shares,
    the half-full ball (u = 0), and the ends."""
    c = torch.cat([torch.rand(3000, dtype=torch.float64), torch.tensor([0.0, 0.5, 1.0, 1e-300, 1 - 1e-16])])
    torch.testing.assert_close(depth_from_share(c), depth_from_fraction(c), rtol=0, atol=1e-12)
    assert abs(float(depth_from_share(torch.tensor([0.5], dtype=torch.float64)))) < 1e-12


def test_shares_outside_the_unit_range_read_as_its_ends():
    """A share above 1 (rounding in a sum of kernel weights) is a ball filled: u at 1 (F(u) = 1), depth R; below 0:
    u at −1 (F(u) = 0) — where F is flat, within 1e-4 of the end."""
    out = depth_from_share(torch.tensor([1.5, 1.0 + 1e-9, -0.25, -1e-12], dtype=torch.float64))
    torch.testing.assert_close(out, torch.tensor([1.0, 1.0, -1.0, -1.0], dtype=torch.float64), rtol=0, atol=1e-4)
    ends = torch.tensor([1.0, 1.0, 0.0, 0.0], dtype=torch.float64)
    torch.testing.assert_close(fraction_of_half_space(out), ends, rtol=0, atol=1e-12)


def test_no_share_is_no_launch_and_no_error():
    """An empty frame (no particle behind another piece) returns an empty float64 tensor."""
    out = depth_from_share(torch.zeros(0, dtype=torch.float64))
    assert out.shape == (0,) and out.dtype == torch.float64


def test_a_float32_share_is_inverted_in_float64():
    """Shares given in float32 are inverted in float64 (the depth keeps the bisection's resolution)."""
    c = torch.tensor([0.25, 0.75], dtype=torch.float32)
    out = depth_from_share(c)
    assert out.dtype == torch.float64
    torch.testing.assert_close(out, depth_from_fraction(c.double()), rtol=0, atol=1e-12)
