"""Pinned rules of a given capture.scale (`capture.scene._fit`), round eight: the scale decides the object's size,
its longest fitted side = scale × its longest side in scene units, which must lie within MIN_CAPTURE_SIZE to
MAX_CAPTURE_SIZE (1 mm to 100 m, both included); outside, the SceneError names the file, the key and the size it
makes, and suggests the scale that gives capture.size (capture.size over the longest side in scene units).
Inside, capture.size follows the scale and the note says so; the fit note lists what was given and what was
found.

The object: the 8 corners of a box 2 × 1 × 0.5 scene units, up = +z, rotation given as the identity (so its
longest side is exactly 2 scene units, whatever the heading), capture.size = 0.5 m unless stated.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import torch

from fracture_gs.capture.scene import _fit
from fracture_gs.config import CaptureConfig
from fracture_gs.errors import SceneError
from fracture_gs.io.gaussian_set import GaussianSet

F64 = torch.float64
EYE = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
UP_NOTE = "up axis +z (capture.up)"


def box() -> GaussianSet:
    c = torch.tensor([[x, y, z] for x in (0.0, 2.0) for y in (0.0, 1.0) for z in (0.0, 0.5)])
    quats = torch.zeros(8, 4)
    quats[:, 0] = 1.0
    return GaussianSet(c, quats, torch.full((8, 3), 0.01), torch.full((8,), 0.9), torch.zeros(8, 1, 3))


def fit_with(**given):
    cap = CaptureConfig(**given)
    notes = []
    Q = None if cap.rotation is None else torch.tensor(cap.rotation, dtype=F64)
    up = torch.tensor([0.0, 0.0, 1.0], dtype=F64)
    t = _fit(box(), up, UP_NOTE, Q, cap, Path("s.ply"), notes)
    return t, cap, notes


@pytest.mark.parametrize(
    "scale, size, makes, near",
    [
        (1e3, 0.5, "2000", "0.25"),  # 1000 × 2 = 2000 m; 0.5 m over 2 scene units = 0.25
        (1e-4, 0.5, "0.0002", "0.25"),  # 0.2 mm
        (1e3, 2.0, "2000", "1"),  # capture.size 2 m: 2 / 2 = 1
        (math.nextafter(50.0, 100.0), 0.5, "100", "0.25"),  # one ulp over 100 m
        (math.nextafter(5e-4, 0.0), 0.5, "0.001", "0.25"),  # one ulp under 1 mm
    ],
)
def test_a_scale_that_makes_the_object_too_big_or_too_small_suggests_the_scale_for_capture_size(
    scale, size, makes, near
):
    """Outside 1 mm to 100 m the given scale is refused in one sentence: the file, the key and its value, the
    size it makes, the range, and the scale that gives capture.size (capture.size / 2 scene units)."""
    with pytest.raises(SceneError) as info:
        fit_with(scale=scale, size=size, rotation=EYE)
    assert str(info.value) == (
        f"s.ply: capture.scale = {scale:g} makes the object's longest side {makes} m, outside 0.001 to 100 m; give "
        f"a scale near {near} (capture.size over the longest side), or remove capture.scale."
    )


@pytest.mark.parametrize("scale, size", [(50.0, 100.0), (5e-4, 1e-3), (0.1, 0.2), (0.25, 0.5)])
def test_a_scale_within_the_range_sets_capture_size(scale, size):
    """100 m and 1 mm themselves are allowed; the scale is used as given and capture.size becomes the longest
    fitted side (noted when it changes: 0.5 m → 0.2 m; a scale giving 0.5 m changes nothing and adds no note).
    The fit note names what was given (scale and rotation) and what was automatic (offset)."""
    t, cap, notes = fit_with(scale=scale, rotation=EYE)
    assert t.scale == scale and cap.size == size
    follows = f"capture.size 0.5 m follows capture.scale: the longest side is {size:.4g} m"
    fit_note = (
        f"fit: capture.scale and capture.rotation from the config, offset automatic ({UP_NOTE}); scale {scale:.4g} "
        f"m per scene unit, longest side {size:g} m"
    )
    assert notes == ([fit_note] if size == 0.5 else [follows, fit_note])


def test_the_fit_note_for_nothing_given_and_for_everything_given():
    """No scale, rotation or offset given: the note states the up axis, the scale found (0.5 m / 2 = 0.25) and
    capture.size; all three given: it says the fit is the config's, with its scale."""
    t, cap, notes = fit_with()
    assert t.scale == 0.25 and notes == [f"{UP_NOTE}; scale 0.25 m per scene unit, longest side 0.5 m"]
    t, cap, notes = fit_with(scale=0.25, rotation=EYE, offset=(0.0, 0.0, 0.0))
    assert t.offset.tolist() == [0.0, 0.0, 0.0] and notes == ["fit from the config: scale 0.25 m per scene unit"]
