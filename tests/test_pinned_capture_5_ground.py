"""Pinned rules of the ground finder (`capture.ground.find_ground`), round five, on a scene whose histogram is
known bin by bin, so every number is a hand computation:

- heights h = z in a 600-Gaussian scene: 26 at h = 0 and 10 at h = 1 (so the robust range, the 0.5 % and 99.5 %
  quantiles, is exactly [0, 1] and a bin is 1 % of it, 0.01); a "skirt" of 13 Gaussians at the centre of each
  of the bins 1–17 and 23–29; a pavement sheet of S Gaussians at h = 0.205, the middle of bin 20 (not the
  lowest bin: the level is read from the fullest bin's index); an object of O Gaussians from h = 0.31 to 0.99;
- the lowest 30 bins hold T = 26 + 24·13 + S Gaussians; with S = 52, T = 390 and the sheet's bin holds exactly
  4 (MIN_PEAK) times the mean of 13: a spike at the threshold is a spike;
- the ground's top is two bins above the centre of the sheet's bin: 0.205 + 0.02 = 0.225;
- its layer (within two bins of the level) holds only the sheet: S of N = 390 + O + 10 Gaussians.

The rule holds in any unit: a scene in kilometres or millimetres finds the same ground, scaled.
"""

from __future__ import annotations

import math

import pytest
import torch

from fracture_gs.capture.ground import MIN_PEAK, MIN_SHARE, find_ground

UP = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64)
SKIRT_BINS = [*range(1, 18), *range(23, 30)]  # 24 bins; none within two bins of the sheet's bin 20
TOP = 0.225  # the sheet's level 0.205 (bin 20's centre) + two bins of 0.01


def _spread(n: int, half: float, seed: int) -> torch.Tensor:  # [n, 2]
    """n horizontal positions, uniform within ±half (deterministic)."""
    g = torch.Generator().manual_seed(seed)
    return (torch.rand(n, 2, generator=g, dtype=torch.float64) * 2 - 1) * half


def _layer(heights, half: float, seed: int) -> torch.Tensor:  # [n, 3]
    h = torch.as_tensor(heights, dtype=torch.float64)
    return torch.cat([_spread(len(h), half, seed), h[:, None]], 1)


def scene(sheet: int = 52, obj: int = 200) -> torch.Tensor:  # [N, 3]
    """The scene of the module doc: N = 26 + 312 + sheet + obj + 10 Gaussians."""
    skirt = [(k + 0.5) * 0.01 for k in SKIRT_BINS for _ in range(13)]
    return torch.cat(
        [
            _layer([0.0] * 26, 1.0, 1),  # the lowest 26: the range's lower end is exactly 0
            _layer(skirt, 0.2, 2),
            _layer([0.205] * sheet, 1.0, 3),  # the pavement, as wide as the scene
            _layer(torch.linspace(0.31, 0.99, obj).tolist(), 0.2, 4),
            _layer([1.0] * 10, 0.2, 5),  # the highest 10: the range's upper end is exactly 1
        ]
    )


def test_the_scene_is_what_the_module_doc_says():
    """The hand computation's premises: the 0.5 % and 99.5 % quantiles are exactly 0 and 1, and the sheet's bin
    holds MIN_PEAK times the mean of the lowest 30 bins (52 = 4 · 390 / 30)."""
    h = scene()[:, 2]
    assert len(h) == 600
    assert torch.quantile(h, torch.tensor([0.005, 0.995], dtype=torch.float64)).tolist() == [0.0, 1.0]
    low = h[h < 0.3]
    assert len(low) == 390 and int((low == 0.205).sum()) == 52 == MIN_PEAK * len(low) / 30


def test_the_level_is_read_from_the_fullest_bins_index():
    """A sheet in bin 20 (h = 0.205, above a skirt of lower Gaussians): the ground's top is the centre of that
    bin plus two bins, 0.225; one bin more or less, a bin of another width or a histogram of another bin count
    would put it elsewhere."""
    assert find_ground(scene(), UP) == pytest.approx(TOP, abs=1e-12)


@pytest.mark.parametrize("unit", [1e-3, 1.0, 1e3, 1e5])
def test_the_ground_is_found_in_any_unit(unit):
    """The finder works in fractions of the height range: the same scene in millimetres, metres, kilometres
    or at 1e5 scene units finds the same ground, scaled (a threshold in absolute units would not)."""
    assert find_ground(scene() * unit, UP) == pytest.approx(TOP * unit, rel=1e-9)


def test_the_ground_is_found_along_any_up_axis():
    """Rotating the scene and its up vector together finds the same level: only heights along `up` count, and
    the spread is measured across it."""
    a, b = 0.7, -1.1
    rz = torch.tensor([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]], dtype=torch.float64)
    rx = torch.tensor([[1, 0, 0], [0, math.cos(b), -math.sin(b)], [0, math.sin(b), math.cos(b)]], dtype=torch.float64)
    R = rx @ rz
    assert find_ground(scene() @ R.T, R @ UP) == pytest.approx(TOP, abs=1e-9)


def test_a_spike_exactly_at_min_peak_is_a_ground_one_less_is_not():
    """The sheet's bin must hold at least MIN_PEAK (4) times the mean count of the lowest 30 bins: 52 Gaussians
    against a mean of 390/30 = 13 is exactly 4 and is the ground; 51 against 389/30 is 3.93 and is not (its
    share, 51/599, and what lies above would pass)."""
    assert find_ground(scene(sheet=52), UP) == pytest.approx(TOP, abs=1e-12)
    assert 51 / 599 > MIN_SHARE
    assert find_ground(scene(sheet=51), UP) is None


@pytest.mark.parametrize("obj, found", [(200, True), (240, True), (260, False), (400, False)])
def test_the_layer_must_hold_min_share_of_all(obj, found):
    """The layer within two bins of the level (here only the sheet's 52) must be at least MIN_SHARE (8 %) of all
    Gaussians: of 600 (8.7 %) and 640 (8.1 %) it is the ground; of 660 (7.9 %) or 800 (6.5 %) it is not. The
    skirt Gaussians three bins away are not in the layer (counted, 78 of 660 would pass)."""
    x = scene(obj=obj)
    assert (52 / len(x) >= MIN_SHARE) == found
    top = find_ground(x, UP)
    assert (top == pytest.approx(TOP, abs=1e-12)) if found else top is None
