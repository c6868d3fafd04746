"""Pinned rule of the ground finder (`capture.ground.find_ground`), round ten: what counts as *above* the ground.
A flat layer is the ground only if at least MIN_ABOVE (20 %) of the Gaussians lie above its top (level + two
bins); a Gaussian exactly at the top belongs to the layer (|h − level| ≤ 2 bins), not to the object above it.

The scenes are in units where a bin is exactly 1, so every height and bound is exact in binary: 1000 Gaussians,
26 at height 0 and 10 at 100 (the robust range is exactly [0, 100]), a sheet at 20.5 (the centre of bin 20,
so the level is 20.5 and the top 22.5), 20 Gaussians at or just above the top, and an object of `above`
Gaussians from 31 to 100. The sheet and the low ones spread ±100 horizontally, the rest ±20.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture.ground import MIN_ABOVE, MIN_PEAK, MIN_SHARE, find_ground

F64 = torch.float64
UP = torch.tensor([0.0, 0.0, 1.0], dtype=F64)
N, LEVEL, TOP = 1000, 20.5, 22.5


def _at(heights, seed: int, half: float) -> torch.Tensor:  # [n, 3]: uniform within ±half horizontally
    h = torch.as_tensor(heights, dtype=F64)
    g = torch.Generator().manual_seed(seed)
    xy = (torch.rand(len(h), 2, generator=g, dtype=F64) * 2 - 1) * half
    return torch.cat([xy, h[:, None]], 1)


def scene(above: int, edge: float) -> torch.Tensor:  # [1000, 3]
    """26 at 0, a sheet at the level, 20 at `edge` (the top 22.5, or a little higher), `above` object Gaussians:
    10 at 100 and the rest evenly from 31 to 99."""
    sheet = N - 26 - 20 - above
    return torch.cat(
        [
            _at([0.0] * 26, 1, 100.0),
            _at([LEVEL] * sheet, 2, 100.0),
            _at([edge] * 20, 3, 20.0),
            _at(torch.linspace(31.0, 99.0, above - 10).tolist(), 4, 20.0),
            _at([100.0] * 10, 5, 20.0),
        ]
    )


def test_the_scene_is_what_the_module_doc_says():
    """Premises: the 0.5 % and 99.5 % height quantiles are exactly 0 and 100 (one bin is 1.0); the sheet's bin
    holds far more than MIN_PEAK times the mean of the lowest 30 bins and the layer far more than MIN_SHARE;
    200 of 1000 is exactly MIN_ABOVE (as the float32 share the finder computes, 0.2 rounds up, so it passes)
    and 199 is below it."""
    x = scene(200, TOP)
    h = x[:, 2]
    assert len(x) == N
    assert torch.quantile(h, torch.tensor([0.005, 0.995], dtype=F64)).tolist() == [0.0, 100.0]
    assert (N - 246) >= MIN_PEAK * (N - 200) / 30 and (N - 226) / N >= MIN_SHARE
    assert int((h > TOP).sum()) == 200 and int((h == TOP).sum()) == 20
    assert not float((h > TOP).float().mean()) < MIN_ABOVE
    assert float((scene(199, TOP)[:, 2] > TOP).float().mean()) < MIN_ABOVE


@pytest.mark.parametrize(
    "above, edge, found",
    [
        (200, TOP, True),  # exactly 20 % above the top: enough
        (199, TOP, False),  # 19.9 % above; the 20 exactly at the top are ground, not above it
        (190, TOP, False),  # 19 % above, 21 % if the 20 at the top counted
        (190, TOP + 1 / 64, True),  # the same 20 a 64th of a bin higher are above: 21 %
        (400, TOP, True),  # an object well over the ground
        (100, TOP + 1 / 64, False),  # 12 %: a flat scan with a few Gaussians on it
    ],
)
def test_at_least_min_above_of_the_gaussians_lie_strictly_above_the_top(above, edge, found):
    """The ground needs at least MIN_ABOVE (20 %) of all Gaussians strictly above its top (level + 2 bins =
    22.5): 200 of 1000 is enough and 199 is not; Gaussians exactly at the top are part of the layer and do not
    count as above (190 + 20 at the top is no ground), while the same 20 a 64th of a bin higher do (190 + 20
    above is). When found, the ground's top is 22.5."""
    top = find_ground(scene(above, edge), UP)
    assert (top == TOP) if found else top is None
