"""Pinned rules of the statistical outlier filter (`capture.clean.outlier_mask`), round three: k means the k
nearest *other* Gaussians, the threshold is mean + std·σ (σ the sample standard deviation) and is strict, and
the k-d tree gives what a brute-force reading of that rule gives.

Unit-level calls on small point sets.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture.clean import outlier_mask


def brute_force(points: torch.Tensor, k: int, std: float) -> torch.Tensor:  # [N, 3] -> [N] bool
    """The documented criterion written out with all pairwise distances: the mean distance to the k nearest
    other points, above the mean of that over the set plus std sample standard deviations."""
    d = torch.cdist(points.double(), points.double())  # [N, N]
    d.fill_diagonal_(float("inf"))
    mean = d.sort(1).values[:, :k].mean(1)  # [N]
    return mean > mean.mean() + std * mean.std(unbiased=True)


def cloud_with_a_far_pair(n=30, seed=0) -> torch.Tensor:
    """n points in a 0.1 m cube and a tight pair (1 mm apart) 1 m away from it."""
    g = torch.Generator().manual_seed(seed)
    x = 0.1 * torch.rand(n, 3, generator=g, dtype=torch.float64)
    pair = torch.tensor([[1.0, 1.0, 1.0], [1.001, 1.0, 1.0]], dtype=torch.float64)
    return torch.cat([x, pair])


def test_one_neighbour_is_the_nearest_other_gaussian():
    """With k = 1, each Gaussian of a tight pair far from the rest has the other as its one neighbour (1 mm
    away), so the pair is not an outlier; with k = 2 the second neighbour is the far cloud and both are
    outliers, and nothing else is."""
    x = cloud_with_a_far_pair()
    assert not outlier_mask(x, 1, 1.0)[-2:].any()
    two = outlier_mask(x, 2, 1.0)
    assert two[-2:].all() and not two[:-2].any()


def test_equally_spaced_points_are_never_outliers():
    """On a 3 × 3 × 3 lattice of spacing 1 every point's nearest neighbour is exactly 1 away: all distances equal
    the mean and σ = 0, and the strict threshold (mean distance > mean + std·σ) flags none, whatever std."""
    axis = torch.arange(3, dtype=torch.float64)
    x = torch.cartesian_prod(axis, axis, axis)
    for std in (0.0, 0.5, 3.0):
        assert not outlier_mask(x, 1, std).any()


def test_threshold_counts_standard_deviations_of_the_sample():
    """Five points on a line at 0, 1, 2, 3 and 3 + d with k = 1: nearest distances 1, 1, 1, 1, d. For d = 5 the
    mean is 1.8 and the sample σ is √(12.8/4) = 1.789, so the last point (5 > 1.8 + σ·std) is an outlier for
    std = 1.7 (threshold 4.84) and not for std = 1.8 (threshold 5.02): the threshold moves with std, by the
    sample (n − 1) deviation (the population one, 1.6, would flag it at std = 1.8 too)."""
    x = torch.tensor([[0.0, 0, 0], [1.0, 0, 0], [2.0, 0, 0], [3.0, 0, 0], [8.0, 0, 0]], dtype=torch.float64)
    assert outlier_mask(x, 1, 1.7).tolist() == [False, False, False, False, True]
    assert not outlier_mask(x, 1, 1.8).any()


@pytest.mark.parametrize("k", [1, 2, 3, 5])
@pytest.mark.parametrize("std", [0.5, 1.0, 2.0])
def test_outliers_match_the_brute_force_criterion(k, std):
    """On a clustered cloud with scattered far points, the k-d tree's answer is the brute-force one for every
    k and std (the mean over exactly the k nearest other points, the strict threshold with the sample σ)."""
    g = torch.Generator().manual_seed(10 * k + int(4 * std))
    x = torch.cat(
        [
            0.2 * torch.rand(60, 3, generator=g, dtype=torch.float64),
            torch.rand(8, 3, generator=g, dtype=torch.float64) * 3.0 - 1.0,
        ]
    )
    got = outlier_mask(x.float(), k, std)
    want = brute_force(x.float(), k, std)
    assert got.dtype == torch.bool and got.tolist() == want.tolist()
    assert want.any() and not want.all()  # the case really separates the points
