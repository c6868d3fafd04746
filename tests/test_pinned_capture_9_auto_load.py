"""Pinned rule of the automatic load choice (`capture.loads.auto_load`), round nine: `capture.load = "auto"`
picks `shoot` for an object standing on a ground kept static (a fall would sink it through that ground) and
`drop` otherwise, whatever its shape; the drop's reason states how many times taller (z extent) than wide (the
larger of the x and y extents) the object is, to one decimal.

Unit-level calls on hand-made boxes whose three extents all differ, so a wrong axis shows in the ratio.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture.loads import auto_load

F64 = torch.float64
SHOOT_WHY = "it stands on its captured ground, which stays static: a fall would sink it through it"


def box(lo, hi):
    return torch.tensor(lo, dtype=F64), torch.tensor(hi, dtype=F64)


@pytest.mark.parametrize(
    "lo, hi, ratio",
    [
        # 0.5 wide along x, 0.2 deep along y, 1.5 tall: 1.5 / 0.5 = 3.0
        ((1.0, 2.0, -0.5), (1.5, 2.2, 1.0), "3.0"),
        # 0.2 along x, 0.8 along y (the wider side), 0.1 tall: 0.1 / 0.8 = 0.125 -> 0.1
        ((-0.3, 0.1, 0.4), (-0.1, 0.9, 0.5), "0.1"),
        # 0.4 along x, 0.25 along y, 0.27 tall: 0.27 / 0.4 = 0.675 -> 0.7 (rounded, not cut)
        ((0.0, 5.0, 3.0), (0.4, 5.25, 3.27), "0.7"),
    ],
)
def test_an_object_without_ground_is_dropped_and_told_its_height_over_width(lo, hi, ratio):
    """No static ground: the fall (`drop`) breaks any shape; the reason gives height / width with height the z
    extent and width the larger horizontal (x or y) extent — 3.0 for a tall post, 0.1 for a flat slab that is
    wider along y than x, 0.7 for 0.27 / 0.4."""
    kind, why = auto_load(*box(lo, hi))
    assert kind == "drop"
    assert why == f"a fall breaks any shape without grips ({ratio}× as tall as wide)"


def test_the_choice_defaults_to_no_ground():
    """Called without `grounded` the object is taken to have no ground under it: `drop`."""
    assert auto_load(*box((0.0, 0.0, 0.0), (1.0, 0.5, 2.0)))[0] == "drop"


@pytest.mark.parametrize("lo, hi", [((1.0, 2.0, -0.5), (1.5, 2.2, 1.0)), ((-0.3, 0.1, 0.4), (-0.1, 0.9, 0.5))])
def test_an_object_on_its_static_ground_is_shot_at_whatever_its_shape(lo, hi):
    """On a captured ground that stays static a fall would sink the object through it: a ball thrown at its
    side (`shoot`) instead, for a tall post and a flat slab alike, with that reason (no shape ratio)."""
    assert auto_load(*box(lo, hi), grounded=True) == ("shoot", SHOOT_WHY)
    assert auto_load(*box(lo, hi), True) == ("shoot", SHOOT_WHY)
