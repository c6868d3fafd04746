"""`capture.ground.find_ground` reads its robust height range (the 0.5 % and 99.5 % quantiles) from at most
200,000 heights: a capture with more Gaussians is sampled without replacement first, so the quantile stays
cheap and never meets torch.quantile's input limit (2²⁴ elements) however large the scan; a smaller one is
read whole. The sample still finds the same ground. torch.quantile is wrapped by a recorder (it calls the
real one) to see what it is given."""

from __future__ import annotations

import torch
from captureutil import quantile_spy

from fracture_gs.capture.ground import find_ground

UP = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64)


def _scene(n: int, seed: int = 0) -> torch.Tensor:
    """A ground sheet (60 % of the points, z in [0, 0.01], 4 m wide) under a 1 m box standing on it."""
    g = torch.Generator().manual_seed(seed)
    n_floor = int(0.6 * n)
    floor = torch.rand(n_floor, 3, generator=g, dtype=torch.float64) * torch.tensor([4.0, 4.0, 0.01])
    box = torch.rand(n - n_floor, 3, generator=g, dtype=torch.float64) + torch.tensor([1.5, 1.5, 0.0])
    return torch.cat([floor, box])


def test_a_large_capture_reads_its_height_range_from_a_sample_of_200000(monkeypatch):
    """200,001 points: the range's quantile is given exactly 200,000 of their heights, all but one of the
    scene's own heights, each drawn once, and the ground is found at the sheet's top."""
    x = _scene(200_001)
    seen = quantile_spy(monkeypatch)
    top = find_ground(x, UP)
    heights = seen[0]
    assert heights.dim() == 1 and len(heights) == 200_000
    # the scene's heights are all distinct: sorted, the sample is theirs with exactly one left out
    h, s = x[:, 2].sort().values, heights.sort().values
    differ = torch.nonzero(s != h[:-1]).flatten()
    k = int(differ[0]) if len(differ) else len(s)
    assert torch.equal(s[:k], h[:k]) and torch.equal(s[k:], h[k + 1 :])
    assert top is not None and 0.01 < top < 0.05, top


def test_a_capture_of_up_to_200000_is_read_whole(monkeypatch):
    """5,000 points: the quantile sees every height (the same multiset), and the ground is the same as found from
    the heights in any order."""
    x = _scene(5_000, seed=1)
    seen = quantile_spy(monkeypatch)
    top = find_ground(x, UP)
    assert torch.equal(seen[0].sort().values, x[:, 2].sort().values)
    assert top is not None and top == find_ground(x.flip(0), UP)
