"""Hand-written bug campaign, round two: the grid's extent and the per-fragment boxes (`sim.grid.domain`,
`sim.boxes.fragment_boxes`), each rule against hand values on both sides of every axis.

- An automatic grid covers `grid_bounds` with wall_cells + 2 spare cells beyond each side, the upper as the lower:
  bounds [1/2, 1] per axis, Δx = 1/16, 2 wall cells → origin 1/4 and 17 nodes (last node at 5/4).
- `max_grid_cells` is the largest grid allowed, itself included.
- A fragment's box is its stencils' bounding box plus the slack, clipped into the grid on both sides; a grid holds
  exactly `max_fragments` boxes.
"""

import pytest
import torch

from fracture_gs import sim as S
from fracture_gs.errors import SimulationError
from fracture_gs.sim.boxes.fragment_boxes import FragmentBoxes
from fracture_gs.sim.grid.domain import check_grid_size, fit_grid


def test_an_automatic_grid_pads_grid_bounds_equally_on_both_sides():
    """Particles inside [1/2, 1]³, grid_bounds [1/2, 1]³, Δx = 1/16, wall_cells = 2, no margin: origin 1/4 on every
    axis, 17 nodes, so the last node (5/4) is as far above the bounds as the origin is below them."""
    cfg = S.SimConfig(dx=1 / 16, grid="auto", grid_margin=0.0, wall_cells=2, grid_bounds=((0.5,) * 3, (1.0,) * 3))
    x = torch.tensor([[0.6, 0.7, 0.8], [0.9, 0.8, 0.7]])
    origin, dx, shape = fit_grid(cfg, x)
    assert origin == (0.25, 0.25, 0.25)
    assert shape == (17, 17, 17)
    top = [o + (s - 1) * dx for o, s in zip(origin, shape)]
    assert [t - 1.0 for t in top] == [0.5 - o for o in origin]


def test_max_grid_cells_allows_a_grid_of_exactly_that_many_nodes():
    """A cap of 8·9·10 = 720 nodes: 8×9×10 passes, 8×9×11 is refused with the key named."""
    check_grid_size((8, 9, 10), 0.1, 720, "sim.grid_shape")
    with pytest.raises(SimulationError, match="max_grid_cells"):
        check_grid_size((8, 9, 11), 0.1, 720, "sim.grid_shape")


def test_boxes_are_clipped_into_the_grid_on_both_sides_and_max_fragments_fit():
    """A 16³ grid (Δx = 1/16), 3 boxes (max_fragments = 3): fragment 0 at the lowest corner, fragment 1 at the highest,
    fragment 2 in the middle; slack 4 nodes. Every box starts at node ≥ 0 and ends at node ≤ 15 on every axis, the
    corner boxes reach those limits, the middle one spans its stencil (base ⌊ξ − ½⌋ … base + 2) plus 4 each way."""
    boxes = FragmentBoxes((16, 16, 16), (0.0, 0.0, 0.0), 1 / 16, "cpu", max_fragments=3)
    x = torch.tensor([[0.07, 0.07, 0.07], [0.93, 0.93, 0.93], [0.5, 0.5, 0.5]])  # ξ = 1.12, 14.88, 8
    boxes.fit(x, torch.tensor([0, 1, 2], dtype=torch.int32), slack=4, K=3)
    lo = boxes.lo[:3].long()
    hi = lo + boxes.dims[:3].long() - 1
    assert lo[0].tolist() == [0, 0, 0] and hi[1].tolist() == [15, 15, 15]
    assert lo[2].tolist() == [3, 3, 3] and hi[2].tolist() == [13, 13, 13]  # base 7: 7 − 4 … 9 + 4
    assert bool((lo >= 0).all()) and bool((hi <= 15).all())
    with pytest.raises(ValueError, match="do not fit"):
        boxes.fit(x, torch.tensor([0, 1, 3], dtype=torch.int32), slack=4)
