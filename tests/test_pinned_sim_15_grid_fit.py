"""`sim.grid.domain.fit_grid` and `check_grid_size`, against hand values:

- an automatic grid refuses bounds that are not finite on EITHER side with its own one-sentence error (not a
  bare OverflowError from rounding an infinite corner): a `sim.grid_bounds` corner at +inf only, at −inf only,
  and NaN positions;
- a finite automatic grid is the particles' bounds padded by `grid_margin` of their extent plus (wall cells + 2)
  nodes, the origin rounded down to a multiple of Δx, one node past the upper corner;
- the oversize message writes the node count with thousands separators below 10¹⁵ and in 3-digit scientific form
  from 10¹⁵ on (10¹⁵ itself included), so the switch sits exactly at 10¹⁵."""

import dataclasses

import pytest
import torch

from fracture_gs.config import SimConfig
from fracture_gs.errors import SimulationError
from fracture_gs.sim.grid.domain import check_grid_size, fit_grid

X = torch.tensor([[0.0, 0.0, 0.0], [1.0, 0.5, 0.25]])


def _auto(**kw):
    return dataclasses.replace(SimConfig(), grid="auto", dx=0.125, grid_margin=0.5, wall_cells=2, **kw)


@pytest.mark.parametrize(
    "bounds",
    [((0.0, 0.0, 0.0), (1.0, float("inf"), 1.0)), ((float("-inf"), 0.0, 0.0), (1.0, 1.0, 1.0))],
    ids=["upper-inf", "lower-inf"],
)
def test_an_infinite_grid_bounds_corner_on_either_side_is_refused_in_one_sentence(bounds):
    """One infinite corner of `sim.grid_bounds` (the other side finite) makes the fitted grid infinite: the fit
    stops with the package's error naming the non-finite bounds, whichever side is infinite."""
    with pytest.raises(SimulationError, match="bounds are not finite; remove NaN or inf positions"):
        fit_grid(_auto(grid_bounds=bounds), X)


def test_nan_positions_are_refused_in_one_sentence():
    """A NaN particle position makes both corners NaN: the same error, before any size arithmetic."""
    x = torch.tensor([[0.0, 0.0, 0.0], [float("nan"), 0.5, 0.25]])
    with pytest.raises(SimulationError, match="not finite"):
        fit_grid(_auto(), x)


def test_a_finite_automatic_grid_pads_by_margin_and_wall_cells():
    """Particles spanning [0, 1] × [0, 0.5] × [0, 0.25], Δx = 1/8, margin 0.5, 2 wall cells: pad = 0.5 · extent +
    4 Δx = (1, 0.75, 0.625) m, so the corners are (−1, −0.75, −0.625) and (2, 1.25, 0.875); the origin is the
    lower corner rounded down to Δx (all already multiples here) and shape = ⌈(hi − origin)/Δx⌉ + 1 nodes."""
    origin, dx, shape = fit_grid(_auto(), X)
    assert dx == 0.125
    assert origin == (-1.0, -0.75, -0.625)
    assert shape == (25, 17, 13)


def test_grid_bounds_widen_the_fitted_grid_by_the_wall_cells_only():
    """`grid_bounds` reaching past the padded particles extend the grid to the bounds ± (wall cells + 2) Δx (no
    margin on the bounds): bounds up to z = 3 give an upper corner 3 + 0.5 = 3.5, 29 nodes from −0.625."""
    origin, _, shape = fit_grid(_auto(grid_bounds=((0.0, 0.0, 0.0), (1.0, 0.5, 3.0))), X)
    assert origin == (-1.0, -0.75, -0.625)
    assert shape == (25, 17, 34)


def test_the_node_count_turns_scientific_exactly_at_ten_to_the_fifteen():
    """10¹⁵ − 1 nodes (one absurd axis) reads 999,999,999,999,999; 10¹⁵ nodes (100000³) reads 1e+15; both with the
    GiB at 32 bytes a node."""
    with pytest.raises(SimulationError) as err:
        check_grid_size((999_999_999_999_999, 1, 1), 0.01, 1000, "an automatic grid")
    msg = str(err.value)
    assert msg.startswith("an automatic grid would be 1e+15×1×1 = 999,999,999,999,999 nodes (≈ 2.98e+07 GiB"), msg
    with pytest.raises(SimulationError) as err:
        check_grid_size((100_000, 100_000, 100_000), 0.01, 1000, "sim.grid_shape")
    msg = str(err.value)
    assert msg.startswith("sim.grid_shape would be 100000×100000×100000 = 1e+15 nodes (≈ 2.98e+07 GiB"), msg


def test_a_grid_exactly_at_the_cap_is_accepted():
    """The cap is inclusive: 10 × 10 × 10 = 1000 nodes under a cap of 1000 passes, 1001 nodes (7 × 11 × 13) do not."""
    check_grid_size((10, 10, 10), 0.01, 1000, "sim.grid_shape")
    with pytest.raises(SimulationError, match="= 1,001 nodes"):
        check_grid_size((7, 11, 13), 0.01, 1000, "sim.grid_shape")
