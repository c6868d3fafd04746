"""Hand-written bug campaign, round three: the interface metrics (`sim.diagnostics.metrics`), each rule against a
hand computation.

- `penetration` and `interface_pairs` walk fragment 0's band members in chunks (memory bound); the result is the
  same for every chunk size, so a member in the last chunk counts as much as one in the first.
- `per_fragment_sum` adds each value to its fragment's row for ids 0 … K − 1 and drops ids outside (−1, K), the
  same on every row count.
"""

import pytest
import torch

from fracture_gs.sim.diagnostics.metrics import band_members, interface_pairs, penetration, per_fragment_sum


def _interface():
    """Five band particles of fragment 0 at x = 0 on y = 0 … 4 (the last one pushed to x = 0.3) and five band
    particles of fragment 1 at x = 0.1 on the same y; a sixth fragment-1 band particle at x = −5, y = 4, far
    behind the last but farther than the radius; a fragment-1 particle outside the band at x = −1, y = 2."""
    xa = torch.tensor([[0.0, float(k), 0.0] for k in range(5)])
    xa[4, 0] = 0.3
    xb = torch.tensor([[0.1, float(k), 0.0] for k in range(5)] + [[-5.0, 4.0, 0.0], [-1.0, 2.0, 0.0]])
    x = torch.cat([xa, xb])
    fragment = torch.tensor([0] * 5 + [1] * 7, dtype=torch.int32)
    band = torch.tensor([1] * 11 + [0], dtype=torch.int32)
    return x, fragment, band


@pytest.mark.parametrize("chunk", [1, 2, 3, 4, 2048])
def test_penetration_is_the_deepest_near_pair_whatever_the_chunk(chunk):
    """n = +x, radius 0.5 m: the near pairs are (a_k, b_k) with depths (x_a − x_b)·n = −0.1 for k < 4 and
    0.3 − 0.1 = 0.2 for k = 4 (the last member, in the last chunk for every chunk size below 5); the far particle
    (5.3 m away) and the non-band one do not count: 0.2 m."""
    x, fragment, band = _interface()
    n = torch.tensor([1.0, 0.0, 0.0], dtype=torch.float64)
    got = penetration(x, band_members(fragment, band), n, 0.5, chunk=chunk)
    assert float(got) == pytest.approx(0.2, abs=1e-6)


@pytest.mark.parametrize("chunk", [1, 2, 3, 2048])
def test_interface_pairs_pair_every_member_whatever_the_chunk(chunk):
    """Radius 0.5 m: every fragment-0 band particle k pairs with fragment 1's band particle on its own y (index
    5 + k), the last one included; none pairs with the far or the non-band particle."""
    x, fragment, band = _interface()
    p, q = interface_pairs(x, fragment, band, 0.5, chunk=chunk)
    assert p.tolist() == [0, 1, 2, 3, 4]
    assert q.tolist() == [5, 6, 7, 8, 9]


def test_per_fragment_sum_keeps_ids_below_k_and_drops_the_rest():
    """K = 3: values 1, 2, 4, 8, 16, 32 of fragments 0, 1, 2, 3, −1, 2 sum to [1, 2, 36]; 8 (id K) and 16 (id −1)
    are dropped, not clamped into the last or the first row."""
    values = torch.tensor([1.0, 2.0, 4.0, 8.0, 16.0, 32.0], dtype=torch.float64)
    fragment = torch.tensor([0, 1, 2, 3, -1, 2])
    assert per_fragment_sum(values, fragment, 3).tolist() == [1.0, 2.0, 36.0]
