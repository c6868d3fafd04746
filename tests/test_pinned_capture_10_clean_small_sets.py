"""Pinned rule of the statistical outlier filter (`capture.clean.outlier_mask`), round ten: how small a set it
judges. With k neighbours a set needs at least k + 2 Gaussians: then every Gaussian has k other neighbours and
the set has a spread of neighbour distances to compare against; a set of k + 1 or fewer (or k ≤ 0) has no
outliers at all. Both sides of the bound are tested on points on a line whose distances are worked out by hand,
where the criterion (mean distance to the k nearest above mean + std·σ, σ the sample deviation) flags the far
point whenever it is applied.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture.clean import outlier_mask


def line(*xs: float) -> torch.Tensor:  # [N, 3] points on the x axis
    x = torch.tensor(xs, dtype=torch.float64)
    return torch.stack([x, torch.zeros_like(x), torch.zeros_like(x)], 1)


def test_k_plus_two_gaussians_are_judged_with_one_neighbour():
    """k = 1 and three Gaussians (k + 2) at 0, 0.1 and 10: nearest distances 0.1, 0.1, 9.9, mean 3.367, sample
    σ = √(64.03/2) = 5.658, so the threshold at std = 1 is 9.024 and the Gaussian at 10 (9.9 above it) is an
    outlier, the other two are not; at std = 1.2 the threshold is 10.16 and none is."""
    x = line(0.0, 0.1, 10.0)
    assert outlier_mask(x, 1, 1.0).tolist() == [False, False, True]
    assert outlier_mask(x, 1, 1.2).tolist() == [False, False, False]


def test_k_plus_two_gaussians_are_judged_with_two_neighbours():
    """k = 2 and four Gaussians (k + 2) at 0, 0.1, 0.2 and 10: mean distances to the two nearest 0.15, 0.1,
    0.15, 9.85, mean 2.5625, sample σ = 4.858, threshold at std = 1 7.42: only the Gaussian at 10 is an
    outlier."""
    assert outlier_mask(line(0.0, 0.1, 0.2, 10.0), 2, 1.0).tolist() == [False, False, False, True]


@pytest.mark.parametrize(
    "points, k",
    [
        ((0.0, 0.1, 10.0), 2),  # k + 1 Gaussians: the criterion would flag the one at 10 (9.95 > 9.51)
        ((0.0, 0.1, 0.2, 10.0), 3),  # k + 1 again, one neighbour more
        ((0.0, 0.1, 10.0), 5),  # fewer Gaussians than neighbours asked for
        ((0.0, 0.1, 10.0), 0),  # k = 0: the filter is off
        ((0.0, 0.1, 10.0), -1),
        ((), 3),  # an empty set
    ],
)
def test_a_set_of_at_most_k_plus_one_gaussians_or_k_off_has_no_outliers(points, k):
    """A set of k + 1 Gaussians or fewer is too small to judge, and k ≤ 0 turns the filter off: the mask is all
    False and as long as the set, even where the criterion itself would flag the far Gaussian (k = 2 on 0, 0.1,
    10: mean distances 5.05, 5.0, 9.95 against a threshold of 9.51 at std = 1)."""
    x = line(*points) if points else torch.zeros(0, 3, dtype=torch.float64)
    mask = outlier_mask(x, k, 1.0)
    assert mask.dtype == torch.bool and mask.tolist() == [False] * len(points)
