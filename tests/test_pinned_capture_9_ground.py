"""`capture.ground.find_ground` on a ten-Gaussian column whose quantiles and bins are worked out by hand: the
ground is looked for only among the Gaussians of the low band (the lowest 30 % of the robust height range
above its 0.5 % quantile), and the level is the fullest bin's centre, its top two bins higher."""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture.ground import find_ground

F64 = torch.float64
UP = torch.tensor([0.0, 0.0, 1.0], dtype=F64)


def column(heights) -> torch.Tensor:  # [N, 3] Gaussians on the up axis (no horizontal spread at all)
    h = torch.tensor(heights, dtype=F64)
    return torch.stack([torch.zeros_like(h), torch.zeros_like(h), h], 1)


def test_an_empty_low_band_has_no_ground():
    """Heights 0, 0.95 and eight at 3: the 0.5 % quantile (position 0.045 of 9) is lo = 0.045·0.95 = 0.04275,
    the 99.5 % one hi = 3, a bin w = (hi − lo)/100 = 0.02957, and the low band [lo, lo + 30w) = [0.04275, 0.93)
    holds no Gaussian (0.95 lies just above it), so there is no ground, even though the Gaussian at 0 is within
    two bins of the first bin's centre and would be 10 % of the scene with 90 % above it."""
    assert find_ground(column([0.0, 0.95] + [3.0] * 8), UP) is None


def test_the_level_is_the_fullest_bins_centre_and_the_top_two_bins_above():
    """Heights 0, 0.5 and eight at 3: lo = 0.045·0.5 = 0.0225, hi = 3, w = 0.029775; the low band holds only
    0.5, in bin ⌊(0.5 − lo)/w⌋ = 16, a spike (1 against a mean of 1/30); its level is lo + 16.5w and the
    ground's top lo + 18.5w = 0.5733375. The layer (the Gaussian at 0.5, 10 % ≥ 8 %) and the 80 % above it
    pass, and its spread (0) is not below 0.8 of the column's (0)."""
    lo, w = 0.0225, (3.0 - 0.0225) / 100
    assert find_ground(column([0.0, 0.5] + [3.0] * 8), UP) == pytest.approx(lo + 18.5 * w, abs=1e-12)


def test_a_bin_exactly_min_peak_times_the_mean_is_a_spike():
    """Twenty Gaussians: two at 0 and three at 100 fix lo = 0 and hi = 100 (1 m bins), thirteen lie one per
    bin at 3.5 … 15.5 and two at 40 and 60. The low band holds 15 in 30 bins (mean 0.5) and the fullest bin
    (0) holds 2, exactly MIN_PEAK = 4 times the mean: that is a spike, so the ground is the two at 0 (10 % of
    the scene, 90 % above), its top at the bin's centre 0.5 plus two bins, 2.5. Moving the Gaussian at 40 into
    the band (at 16.5) lifts the mean to 16/30, so 2 is below 4 times it: no spike, no ground."""
    spike = [0.0, 0.0] + [b + 0.5 for b in range(3, 16)] + [40.0, 60.0, 100.0, 100.0, 100.0]
    assert find_ground(column(spike), UP) == pytest.approx(2.5, abs=1e-12)
    flat = [0.0, 0.0] + [b + 0.5 for b in range(3, 17)] + [60.0, 100.0, 100.0, 100.0]
    assert find_ground(column(flat), UP) is None
