"""Pinned rule of capture.size under a given capture.scale (`capture.scene._fit`), round ten: the scale decides the
object's size, and capture.size is replaced by the longest fitted side (with a note saying so) only when the two
differ by more than one part in a million of that side; a capture.size within that relative tolerance (round-off
of a config written and read back) is left as it is and nothing is said. The tolerance is relative, so it is the
same fraction for a 0.5 m and a 4 m object.

The object: the 8 corners of a box 2 × 1 × 0.5 scene units, up = +z, rotation given as the identity, so its
longest side is exactly 2 scene units and the fitted side exactly 2 × scale.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from fracture_gs.capture.scene import _fit
from fracture_gs.config import CaptureConfig
from fracture_gs.io.gaussian_set import GaussianSet

F64 = torch.float64
EYE = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


def box() -> GaussianSet:
    c = torch.tensor([[x, y, z] for x in (0.0, 2.0) for y in (0.0, 1.0) for z in (0.0, 0.5)])
    quats = torch.zeros(8, 4)
    quats[:, 0] = 1.0
    return GaussianSet(c, quats, torch.full((8, 3), 0.01), torch.full((8,), 0.9), torch.zeros(8, 1, 3))


def fit(scale: float, size: float):
    cap = CaptureConfig(scale=scale, size=size, rotation=EYE)
    notes = []
    up = torch.tensor([0.0, 0.0, 1.0], dtype=F64)
    t = _fit(box(), up, "up axis +z (capture.up)", torch.tensor(EYE, dtype=F64), cap, Path("s.ply"), notes)
    return t, cap, notes


@pytest.mark.parametrize(
    "scale, side, size, follows",
    [
        (0.25, 0.5, 0.5 + 1e-6, True),  # 2e-6 of the side: replaced
        (0.25, 0.5, 0.5 - 1e-6, True),  # below as above
        (0.25, 0.5, 0.5 + 4e-7, False),  # 8e-7 of the side: within the tolerance
        (0.25, 0.5, 0.5 - 4e-7, False),
        (2.0, 4.0, 4.0 + 1e-5, True),  # 2.5e-6 of a 4 m side: replaced
        (2.0, 4.0, 4.0 + 2e-6, False),  # 5e-7 of a 4 m side: kept (an absolute 1e-6 m would replace it)
        (2.0, 4.0, 4.0 - 2e-6, False),
        (0.25, 0.5, 0.2, True),  # far off: replaced
    ],
)
def test_capture_size_follows_the_scale_beyond_one_part_in_a_million(scale, side, size, follows):
    """The fitted side is 2 × scale (0.5 m or 4 m). capture.size off by more than 1e-6 of that side, above or below,
    becomes the side and the first note says "capture.size <old> m follows capture.scale: the longest side is
    <side> m"; off by less, capture.size is kept exactly and only the fit note is written."""
    t, cap, notes = fit(scale, size)
    assert t.scale == scale
    if follows:
        assert cap.size == side
        assert notes[0] == f"capture.size {size:g} m follows capture.scale: the longest side is {side:.4g} m"
        assert len(notes) == 2
    else:
        assert cap.size == size
        assert len(notes) == 1 and not notes[0].startswith("capture.size")
    assert notes[-1].endswith(f"scale {scale:.4g} m per scene unit, longest side {cap.size:g} m")
