"""The depth inversion is a bisection of [−1, 1] halved exactly 40 times, in Warp and in its torch twin.

After k halvings of [−1, 1] the interval is 2·2⁻ᵏ wide with dyadic ends, and the answer is its midpoint: an odd
multiple of 2⁻ᵏ. With k = 40 (`HALVINGS`, u to 2⁻⁴⁰ as documented) every returned u times 2⁴⁰ is an odd integer
(exact in float64: 41 significant bits at most). One halving more or less shows: u·2⁴⁰ is then a half-integer
or even."""

import torch

from fracture_gs.sim.diagnostics import penetration_kernels as pk
from fracture_gs.sim.diagnostics.penetration import depth_from_fraction, fraction_of_half_space


def _shares() -> torch.Tensor:
    """Shares across [0, 1], its ends, values outside it, and the shares of a few exact u."""
    u = torch.tensor([-0.75, -0.5, 0.0, 0.125, 0.5, 0.9], dtype=torch.float64)
    rand = torch.rand(400, dtype=torch.float64, generator=torch.Generator().manual_seed(14))
    return torch.cat([rand, torch.tensor([0.0, 1.0, 0.5, -0.25, 1.5], dtype=torch.float64), fraction_of_half_space(u)])


def _odd_multiples_of_2_to_minus_40(u: torch.Tensor) -> bool:
    k = u * 2.0**40
    return bool((k == torch.round(k)).all()) and bool((torch.remainder(k, 2.0) == 1.0).all())


def test_the_warp_inversion_halves_forty_times():
    """Every u from the Warp kernel is an odd multiple of 2⁻⁴⁰ (the midpoint of the 40th interval)."""
    u = pk.depth_from_share(_shares())
    assert _odd_multiples_of_2_to_minus_40(u)
    assert float(u.abs().max()) < 1.0, "the midpoint never reaches an end of [−1, 1]"


def test_the_torch_twin_halves_forty_times():
    """The torch twin returns the same grid of answers: odd multiples of 2⁻⁴⁰."""
    assert _odd_multiples_of_2_to_minus_40(depth_from_fraction(_shares()))


def test_the_half_full_ball_reads_the_midpoint_just_below_zero():
    """F(0) = ½ exactly, so for share ½ the first halving (mid = 0, F(mid) < c false) keeps the lower half and
    every later one the upper half: the last interval is [−2⁻³⁹, 0] and the answer −2⁻⁴⁰ in both."""
    half = torch.tensor([0.5], dtype=torch.float64)
    assert float(pk.depth_from_share(half)) == -(2.0**-40)
    assert float(depth_from_fraction(half)) == -(2.0**-40)
