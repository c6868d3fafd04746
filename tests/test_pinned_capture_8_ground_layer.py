"""Pinned rules of the ground finder (`capture.ground.find_ground`), round eight: the two inclusive bounds of the
ground layer, each on a scene whose numbers are exact in binary, so the bound itself is tested, not a point
near it.

The scenes are those of round five (tests/test_pinned_capture_5_ground.py) in units where a bin is exactly 1:
heights from 0 (26 Gaussians) to 100 (10 Gaussians), so the robust range is [0, 100] and a bin 1.0; a skirt of
13 Gaussians at the centre of each bin 1–17 and 23–29; a pavement sheet at 20.5, the centre of bin 20, so the
level is 20.5 and the layer is every Gaussian with |h − 20.5| ≤ 2 (two bins, both ends included); the ground's
top is 22.5; an object above it.

1. The layer's reach: Gaussians exactly two bins from the level (at 18.5 and 22.5) are in the layer, and with
   them it holds MIN_SHARE (8 %) of all; without them (or just beyond two bins) it does not.
2. The layer's spread: its 2–98 % horizontal extent must be at least MIN_SPREAD (0.8) times the whole
   capture's. Every horizontal position is on the x axis: the capture's extent is exactly 10, the sheet's 8
   (= 0.8 · 10 in floating point too) or 8 − 1/32.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture.ground import MIN_ABOVE, MIN_PEAK, MIN_SHARE, MIN_SPREAD, find_ground

F64 = torch.float64
UP = torch.tensor([0.0, 0.0, 1.0], dtype=F64)
SKIRT = [k + 0.5 for k in [*range(1, 18), *range(23, 30)] for _ in range(13)]  # 312 heights
LEVEL, TOP = 20.5, 22.5


def _wide(heights, seed: int) -> torch.Tensor:  # [n, 3]: uniform within ±100 horizontally
    h = torch.as_tensor(heights, dtype=F64)
    g = torch.Generator().manual_seed(seed)
    xy = (torch.rand(len(h), 2, generator=g, dtype=F64) * 2 - 1) * 100.0
    return torch.cat([xy, h[:, None]], 1)


def _narrow(heights, seed: int) -> torch.Tensor:  # [n, 3]: uniform within ±20 horizontally
    x = _wide(heights, seed)
    x[:, :2] *= 0.2
    return x


def reach_scene(edge: float) -> torch.Tensor:  # [800, 3]
    """26 at 0, the skirt, a sheet of 60 at the level, 6 at LEVEL − edge and 6 at LEVEL + edge, 380 object
    Gaussians from 31 to 99, 10 at 100."""
    return torch.cat(
        [
            _wide([0.0] * 26, 1),
            _narrow(SKIRT, 2),
            _wide([LEVEL] * 60, 3),
            _wide([LEVEL - edge] * 6 + [LEVEL + edge] * 6, 4),
            _narrow(torch.linspace(31.0, 99.0, 380).tolist(), 5),
            _narrow([100.0] * 10, 6),
        ]
    )


def test_the_reach_scene_is_what_the_module_doc_says():
    """Premises: 800 Gaussians whose 0.5 % and 99.5 % height quantiles are exactly 0 and 100; the sheet's bin
    (60) is at least MIN_PEAK times the mean of the lowest 30 bins ((26 + 312 + 60 + 12) / 30); the layer's 72
    Gaussians are 9 % of all and the sheet's 60 alone 7.5 %, against MIN_SHARE = 8 %; above the top are
    7 · 13 + 380 + 10 = 481, over MIN_ABOVE."""
    x = reach_scene(2.0)
    h = x[:, 2]
    assert len(x) == 800
    assert torch.quantile(h, torch.tensor([0.005, 0.995], dtype=F64)).tolist() == [0.0, 100.0]
    assert 60 >= MIN_PEAK * (26 + 312 + 60 + 12) / 30
    assert 72 / 800 >= MIN_SHARE > 60 / 800
    assert int((h > TOP).sum()) == 481 and 481 / 800 >= MIN_ABOVE


@pytest.mark.parametrize(
    "edge, found",
    [
        (2.0, True),  # exactly two bins from the level: in the layer, which then holds 72 of 800 (9 %)
        (2.0 + 1 / 64, False),  # just beyond: the layer is the sheet alone, 60 of 800 (7.5 %)
        (1.0, True),  # well within
        (3.0, False),  # the skirt's distance: out
    ],
)
def test_the_layer_reaches_exactly_two_bins_from_the_level_on_both_sides(edge, found):
    """The ground layer is every Gaussian within two bins of the level, both ends included (|h − level| ≤ 2
    bins, below the level as above it): with 12 Gaussians exactly two bins away the layer holds 8 % of all
    and is the ground (its top 22.5); 1/64 of a bin further they are not in it and the sheet alone is too small
    a share."""
    top = find_ground(reach_scene(edge), UP)
    assert (top == TOP) if found else top is None


def spread_scene(half: float) -> torch.Tensor:  # [600, 3]
    """Round five's scene at 100 × its height, every Gaussian on the plane y = 0: the lowest 26 split between
    x = −5 and x = +5 (13 each), the sheet of 52 between x = −half and +half (26 each), everything else at
    x = 0."""
    h = torch.tensor(
        [0.0] * 26 + SKIRT + [LEVEL] * 52 + torch.linspace(31.0, 99.0, 200).tolist() + [100.0] * 10, dtype=F64
    )
    x = torch.zeros(len(h), dtype=F64)
    x[:13], x[13:26] = -5.0, 5.0
    x[338:364], x[364:390] = -half, half
    return torch.stack([x, torch.zeros_like(x), h], 1)


@pytest.mark.parametrize(
    "half, found",
    [
        (4.0, True),  # the sheet spans 8 = 0.8 · 10: exactly MIN_SPREAD of the capture's extent is enough
        (4.0 - 1 / 64, False),  # 8 − 1/32: narrower than MIN_SPREAD of it
        (5.0, True),  # as wide as the whole capture
        (2.0, False),  # a table under a plant: 40 % of the capture's width is not a ground
    ],
)
def test_the_layer_must_spread_at_least_min_spread_of_the_capture(half, found):
    """The layer's 2–98 % horizontal extent must be at least MIN_SPREAD (0.8) of the whole capture's (here 10:
    13 of 600 Gaussians at each of x = ±5 hold both 2 % quantiles): a sheet 8 wide is the ground, one 8 − 1/32
    wide is not, whatever else it passes (4 · 13 = 52 in its bin, 52 / 600 of all, 301 above its top)."""
    x = spread_scene(half)
    assert 0.8 * 10.0 == 8.0 and MIN_SPREAD == 0.8
    q = torch.quantile(x[:, 0], torch.tensor([0.02, 0.98], dtype=F64))
    assert q.tolist() == [-5.0, 5.0]
    top = find_ground(x, UP)
    assert (top == TOP) if found else top is None
