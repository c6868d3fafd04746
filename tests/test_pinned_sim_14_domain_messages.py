"""The grid's two refusals (`sim.grid.domain`) say exactly what they found, so a user can act on them:

- particles outside an explicit grid: how many, the grid's first and last node, and the FIRST particle outside
  in the particles' own order (the one a user finds at the top of the file), rounded to 4 decimals;
- a grid over `sim.max_grid_cells`: its shape as whole node counts (×-joined; only absurd axes of 10⁹ nodes or
  more in 3-digit scientific form), the node count with thousands separators, the GiB at 32 bytes a node, Δx
  and the cap."""

import pytest
import torch

from fracture_gs.errors import SimulationError
from fracture_gs.sim.grid.domain import check_grid_size, check_inside


def test_particles_outside_the_grid_are_counted_and_the_first_one_in_order_is_named():
    """Grid nodes 0 … 4 at Δx = 0.25 m span [0, 1]³. Of four particles, the second (x = 1.5) and the fourth
    (z = −0.25) lie outside: the message counts 2 of 4, states the span, and names (1.5, 0.5, 0.125) — the first
    outside in order, not the last."""
    x = torch.tensor([[0.5, 0.5, 0.5], [1.5, 0.5, 0.125], [1.0, 1.0, 1.0], [0.25, 0.75, -0.25]])
    with pytest.raises(SimulationError) as err:
        check_inside(x, (0.0, 0.0, 0.0), 0.25, (5, 5, 5))
    msg = str(err.value)
    assert msg.startswith("2 of 4 particles start outside the grid [0, 0, 0] to [1, 1, 1] m (first at "), msg
    assert "(first at [1.5, 0.5, 0.125]);" in msg, msg
    assert "sim.grid_origin, sim.grid_shape" in msg and 'sim.grid = "auto"' in msg


def test_a_particle_below_the_grid_is_named_with_four_decimals():
    """One particle of three, at (−0.123456, 0.5, 0.5), below an origin at 0: named rounded to 4 decimals."""
    x = torch.tensor([[0.5, 0.5, 0.5], [-0.123456, 0.5, 0.5], [0.75, 0.5, 0.5]], dtype=torch.float64)
    want = r"^1 of 3 particles start outside .*\(first at \[-0\.1235, 0\.5, 0\.5\]\)"
    with pytest.raises(SimulationError, match=want):
        check_inside(x, (0.0, 0.0, 0.0), 0.25, (5, 5, 5))


def test_an_oversized_grid_names_its_shape_in_whole_nodes():
    """2000 × 3000 × 1500 nodes (9·10⁹) over a cap of 10⁶: the shape reads 2000×3000×1500 (not 2e+03), the count
    9,000,000,000, the memory 9·10⁹ · 32 B = 268 GiB, Δx 0.005 m and the cap 1,000,000."""
    with pytest.raises(SimulationError) as err:
        check_grid_size((2000, 3000, 1500), 0.005, 1_000_000, "sim.grid_shape")
    msg = str(err.value)
    want = "sim.grid_shape would be 2000×3000×1500 = 9,000,000,000 nodes (≈ 268 GiB at Δx = 0.005 m), "
    assert msg.startswith(want + "over sim.max_grid_cells = 1,000,000; "), msg


def test_an_absurd_axis_is_written_in_scientific_form():
    """An axis of 10⁹ nodes or more (a floater kilometres away) is written 3-digit scientific, the others whole:
    (10, 10⁹, 10⁹ − 1) reads 10×1e+09×999999999; the node count over 10¹⁵ is scientific too."""
    with pytest.raises(SimulationError) as err:
        check_grid_size((10, 1_000_000_000, 999_999_999), 0.01, 1000, "an automatic grid")
    msg = str(err.value)
    assert msg.startswith("an automatic grid would be 10×1e+09×999999999 = 1e+19 nodes"), msg
