"""Pinned rule of the fit's heading (`capture.fit.fit_transform`), round eight: after the up axis goes onto +z,
the object turns about z so that its longest horizontal principal axis lies along x, whichever way that axis
pointed (a pull load grips the two ends along x; a turn the wrong way puts the long axis at twice its angle).

The object: 41 points along a horizontal rod of length 2 at the angle α from +x, and 2 points 0.2 either side of
its middle across it, at height 0 (up = +z), so its major horizontal axis is (cos α, sin α, 0) exactly, and 3
points above and below the middle to give it a height of 0.5.
"""

from __future__ import annotations

import math

import pytest
import torch

from fracture_gs.capture.fit import CENTRE, fit_transform

F64 = torch.float64


def rod(alpha: float) -> torch.Tensor:  # [46, 3]
    a = torch.tensor([math.cos(alpha), math.sin(alpha), 0.0], dtype=F64)
    across = torch.tensor([-math.sin(alpha), math.cos(alpha), 0.0], dtype=F64)
    t = torch.linspace(-1.0, 1.0, 41, dtype=F64)
    z = torch.tensor([0.0, 0.0, 1.0], dtype=F64)
    extra = torch.stack([0.2 * across, -0.2 * across, 0.25 * z, -0.25 * z, 0.1 * z])
    return torch.cat([t[:, None] * a, extra])


@pytest.mark.parametrize("degrees", [0.0, 30.0, 60.0, 90.0, 135.0, -20.0, 170.0])
def test_the_long_horizontal_axis_is_turned_onto_x(degrees):
    """A rod at α = 0°, 30°, 60°, 90°, 135°, −20° or 170° from +x ends along ±x: the fitted rotation takes its
    direction to (±1, 0, 0) and keeps +z up, so the fitted object is 2 · scale long in x, 0.4 · scale wide in
    y and 0.5 · scale tall; the scale makes the longest side capture.size (0.5 m) and the bounding box is
    centred on CENTRE."""
    alpha = math.radians(degrees)
    x = rod(alpha)
    up = torch.tensor([0.0, 0.0, 1.0], dtype=F64)
    t = fit_transform(x, up, 0.5)
    a = torch.tensor([math.cos(alpha), math.sin(alpha), 0.0], dtype=F64)
    turned = t.rotation @ a
    assert abs(float(turned[0])) == pytest.approx(1.0, abs=1e-12)
    assert turned[1:].abs().max() < 1e-12
    assert (t.rotation @ up).tolist() == pytest.approx([0.0, 0.0, 1.0], abs=1e-12)
    assert t.scale == pytest.approx(0.25, rel=1e-12)
    y = t.points(x)
    extent = y.max(0).values - y.min(0).values
    assert extent.tolist() == pytest.approx([0.5, 0.1, 0.125], abs=1e-12)
    assert (0.5 * (y.max(0).values + y.min(0).values)).tolist() == pytest.approx(list(CENTRE), abs=1e-12)
