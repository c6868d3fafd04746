"""Pinned rules of the automatic region of interest's robust core (`capture.fit.auto_roi`), round ten:

- the core runs, on every axis alone, from the `percentile` % quantile of the Gaussians to the
  (100 − `percentile`) % quantile (torch's linear interpolation between order statistics), both exactly; its
  voxel is 1/48 of its longest side;
- which apart parts belong to the object follows from those two quantiles on the point: a rod whose last
  Gaussian is the order statistic just below the lower quantile is background, one whose first Gaussian is the
  upper quantile itself is part of the object;
- the quantiles are read from at most 200,000 Gaussians: a capture with more is sampled without replacement
  first (the cost stays that of 200,000 however large the scan), one of up to 200,000 is read whole.

Scenes are rows of points whose order statistics are known by hand; where the voxeller is not the subject, a
spy stands in for `auto_roi_connected` to see the core it is given.
"""

from __future__ import annotations

import pytest
import torch
from captureutil import quantile_spy, voxeller_spy

from fracture_gs.capture.fit import auto_roi

F64 = torch.float64


@pytest.mark.parametrize(
    "percentile, lo, hi",
    [(10.0, [10.0, 20.0, 30.0], [90.0, 180.0, 270.0]), (25.0, [25.0, 50.0, 75.0], [75.0, 150.0, 225.0])],
)
def test_the_core_is_the_percentile_and_its_complement_on_every_axis(monkeypatch, percentile, lo, hi):
    """101 Gaussians at t · (1, 2, 3), t = 0 … 100 (shuffled): the p % quantile of each axis is the order
    statistic at p/100 · 100 = p exactly, so the core of p = 10 is [10, 90] × [20, 180] × [30, 270] and of
    p = 25 it is [25, 75] × [50, 150] × [75, 225]; the voxel is the longest side over 48 (240/48 = 5 and
    150/48), and a grid this small (21 × 41 × 61 voxels at p = 10) is voxelled whole, all 101 Gaussians."""
    t = torch.arange(101, dtype=F64)[torch.randperm(101, generator=torch.Generator().manual_seed(0))]
    x = t[:, None] * torch.tensor([1.0, 2.0, 3.0], dtype=F64)
    seen = voxeller_spy(monkeypatch)
    auto_roi(x, percentile)
    (given, core_lo, core_hi, h) = seen[0]
    assert core_lo == pytest.approx(lo, abs=1e-9) and core_hi == pytest.approx(hi, abs=1e-9)
    assert h == pytest.approx((hi[2] - lo[2]) / 48.0, rel=1e-12)
    assert len(given) == 101


def _rod(x0: float, n: int) -> torch.Tensor:  # [n, 3]
    """n Gaussians 1 mm apart along x from x0 (y = z = 0)."""
    r = torch.zeros(n, 3, dtype=F64)
    r[:, 0] = x0 + 0.001 * torch.arange(n, dtype=F64)
    return r


def test_which_apart_rods_belong_to_the_object_is_decided_at_the_quantiles_themselves():
    """Three rods along x, far apart (0.8 m, about 38 voxels): L, 202 Gaussians from 0 (order statistics 0 …
    201), M, 605 from 1.0 (202 … 806), and H, 204 from 2.0 (807 … 1010). At percentile 20 the lower quantile
    sits at position 0.2 · 1010 = 202, M's first Gaussian, one order statistic above L's last: L is
    background; the upper one at 0.8 · 1010 = 808, H's second Gaussian: H is part of the object. The bounds are
    M's start and H's end, widened by 2 % of their extent (and 1e-9) each side. A lower quantile read at
    20/101 (position 200, inside L) would keep L; an upper one read at 1 − 20/99 (position 805.96, between M
    and H) would drop H."""
    x = torch.cat([_rod(0.0, 202), _rod(1.0, 605), _rod(2.0, 204)])
    lo, hi = auto_roi(x, 20.0)
    pad = 0.02 * (2.203 - 1.0) + 1e-9
    assert lo.tolist() == pytest.approx([1.0 - pad, -1e-9, -1e-9], abs=1e-12)
    assert hi.tolist() == pytest.approx([2.203 + pad, 1e-9, 1e-9], abs=1e-12)


def _numbered(n: int) -> torch.Tensor:  # [n, 3]
    """n distinct Gaussians: row i is (i, i mod 7, i mod 11) · 1 mm, so a row's x names it."""
    i = torch.arange(n, dtype=F64)
    return 0.001 * torch.stack([i, i.remainder(7), i.remainder(11)], 1)


@pytest.mark.parametrize("n", [200_001, 300_000])
def test_the_core_of_a_large_capture_is_read_from_a_sample_of_200000(monkeypatch, n):
    """200,001 or 300,000 Gaussians: the core's quantiles are given exactly 200,000 of them, every one a row
    of the scene, no row twice (a sample without replacement), so the cost stays that of 200,000."""
    x = _numbered(n)
    seen = quantile_spy(monkeypatch)
    auto_roi(x, 1.0)
    s = seen[0]
    assert s.shape == (200_000, 3)
    idx = torch.round(s[:, 0] / 0.001).to(torch.int64)
    assert len(torch.unique(idx)) == 200_000 and int(idx.min()) >= 0 and int(idx.max()) < n
    assert torch.equal(x[idx], s)


@pytest.mark.parametrize("n", [200_000, 5_000])
def test_a_capture_of_up_to_200000_is_read_whole(monkeypatch, n):
    """200,000 (the cap itself) or 5,000 Gaussians: the quantiles see every Gaussian, each once, and the
    core is exactly the one read from the rows in any order (the 1 % and 99 % quantiles of 0 … n − 1 mm)."""
    x = _numbered(n)
    seen = quantile_spy(monkeypatch)
    box = voxeller_spy(monkeypatch)
    auto_roi(x, 1.0)
    s = seen[0]
    assert torch.equal(s[s[:, 0].argsort()], x)
    core_lo, core_hi = box[0][1], box[0][2]
    assert core_lo[0] == pytest.approx(0.01 * (n - 1) * 0.001, abs=1e-12)
    assert core_hi[0] == pytest.approx(0.99 * (n - 1) * 0.001, abs=1e-12)
    auto_roi(x.flip(0), 1.0)
    assert box[1][1:] == box[0][1:]
