"""The scales of the energy bookkeeping (`energy.reference_point`, `energy.relative_change`).

reference_point: the node-box corner lowest along g, i.e. the one with the largest g·x, so every particle inside
the grid has (−g)·(x − x_ref) ≥ 0. Along each axis it is the far end (origin + (shape − 1)·Δx) where g points
up that axis and the origin's end where g points down it. relative_change: (after − before) over the larger of
|before| and |after|, 0 when both are 0 or the scale is not finite."""

import math

import pytest

from fracture_gs.sim.diagnostics.energy import reference_point, relative_change

ORIGIN, DX, SHAPE = (0.5, -1.0, 2.0), 0.25, (5, 9, 3)  # node boxes end at 1.5, 1.0 and 2.5


@pytest.mark.parametrize(
    "gravity, corner",
    [
        ((0.0, 0.0, -9.81), (0.5, -1.0, 2.0)),  # z low; x and y tie: the first corner (origin) among equals
        ((1.0, -2.0, 3.0), (1.5, -1.0, 2.5)),  # +x far, −y near, +z far
        ((-1.0, 2.0, -3.0), (0.5, 1.0, 2.0)),
        ((0.0, 4.0, 0.0), (0.5, 1.0, 2.0)),
    ],
)
def test_the_reference_is_the_corner_lowest_along_gravity(gravity, corner):
    """The whole corner, every axis: far end where g has a positive component, origin end otherwise."""
    assert reference_point(ORIGIN, DX, SHAPE, gravity) == corner


def test_every_node_lies_at_or_above_the_reference():
    """(−g)·(x − x_ref) ≥ 0 at all eight corners of the node box for an oblique g (the reference is the minimum)."""
    g = (0.3, -0.7, 0.2)
    ref = reference_point(ORIGIN, DX, SHAPE, g)
    for k in range(8):
        c = [ORIGIN[a] + (SHAPE[a] - 1) * DX * ((k >> a) & 1) for a in range(3)]
        assert sum(-gi * (ci - ri) for gi, ci, ri in zip(g, c, ref)) >= 0.0


def test_relative_change_is_over_the_larger_magnitude():
    """(after − before) / max(|before|, |after|): 4 → 5 is +0.2, 5 → 4 is −0.2, −4 → −5 is −0.2 (magnitudes, not
    signed values, set the scale), −1 → 1 is +2; 0 → 0 is 0; an infinite total gives 0, not NaN or ±1."""
    assert relative_change(4.0, 5.0) == pytest.approx(0.2)
    assert relative_change(5.0, 4.0) == pytest.approx(-0.2)
    assert relative_change(-4.0, -5.0) == pytest.approx(-0.2)
    assert relative_change(-1.0, 1.0) == 2.0
    assert relative_change(0.0, 0.0) == 0.0
    assert relative_change(1.0, math.inf) == 0.0 and relative_change(-math.inf, 2.0) == 0.0
