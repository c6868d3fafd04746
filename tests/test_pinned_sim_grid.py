"""`sim/grid/domain.py` and `sim/grid/fields.py` host rules: where an automatic grid goes (the particles, their
margin and `grid_bounds`, each padded by the wall cells plus two on both sides), where an explicit origin snaps,
which particles count as inside, the size guard's message, and the grid's memory footprint by buffer."""

import pytest
import torch

from fracture_gs.config import SimConfig
from fracture_gs.errors import SimulationError
from fracture_gs.sim.grid.domain import check_grid_size, check_inside, fit_grid
from fracture_gs.sim.grid.fields import Grid


def _auto(**kw):
    return SimConfig(grid="auto", dx=1 / 16, **kw)


def test_auto_grid_covers_the_bounds_plus_the_wall_cells_on_both_sides():
    """With grid_bounds [0, 1]³ around a small cluster, the nodes span the bounds plus (wall_cells + 2)·Δx on
    each side, the same number of cells below and above: origin −5Δx, 16 + 2·5 cells (27 nodes) per axis."""
    x = torch.full((10, 3), 0.5) + 0.01 * torch.arange(10.0)[:, None]
    cfg = _auto(grid_margin=0.0, wall_cells=3, grid_bounds=((0.0, 0.0, 0.0), (1.0, 1.0, 1.0)))
    origin, dx, shape = fit_grid(cfg, x)
    assert dx == 1 / 16
    assert origin == (-5 / 16,) * 3
    assert shape == (27, 27, 27)
    top = origin[0] + (shape[0] - 1) * dx
    assert top - 1.0 == pytest.approx(0.0 - origin[0])  # symmetric wall padding


def test_auto_grid_pads_the_particles_by_margin_and_wall_cells():
    """Without bounds: the particles' extent E grows by grid_margin·E + (wall_cells + 2)·Δx each way."""
    x = torch.tensor([[1.0, 1.0, 1.0], [2.0, 1.5, 1.25]])
    origin, dx, shape = fit_grid(_auto(grid_margin=0.5, wall_cells=2), x)
    # x: pad 0.5 + 4/16 = 0.75 → [0.25, 2.75]; y: 0.25 + 0.25 → [0.5, 2.0]; z: 0.125 + 0.25 → [0.625, 1.625]
    assert origin == (0.25, 0.5, 0.625)
    assert shape == (41, 25, 17)


def test_explicit_origin_snaps_down_to_a_multiple_of_dx():
    """An explicit origin is rounded down to a multiple of Δx (nodes at integer multiples), tolerating
    float noise just below a multiple: 0.3 with Δx = 0.1 stays at node 3, −0.05 goes to −0.1."""
    cfg = SimConfig(dx=0.1, grid_shape=(8, 8, 8), grid_origin=(0.3, -0.05, 0.0))
    origin, dx, shape = fit_grid(cfg, torch.zeros(1, 3))
    assert origin == pytest.approx((0.3, -0.1, 0.0), abs=1e-12)
    assert shape == (8, 8, 8)


def test_particles_on_the_last_node_are_inside_and_beyond_it_are_not():
    """check_inside accepts particles on the grid's first and last nodes and names the count outside."""
    origin, dx, shape = (0.0, 0.0, 0.0), 0.25, (5, 5, 5)
    check_inside(torch.tensor([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]), origin, dx, shape)
    with pytest.raises(SimulationError, match="1 of 2 particles start outside"):
        check_inside(torch.tensor([[0.5, 0.5, 0.5], [1.0, 1.0, 1.0001]]), origin, dx, shape)
    with pytest.raises(SimulationError, match="1 of 1 particles"):
        check_inside(torch.tensor([[-0.0001, 0.5, 0.5]]), origin, dx, shape)


def test_grid_size_guard_states_the_memory_in_gib():
    """A grid over sim.max_grid_cells is refused before allocating, with its size in GiB: 1024³ nodes at
    32 bytes each are 32 GiB; a grid of exactly the cap is accepted."""
    with pytest.raises(SimulationError, match=r"≈ 32 GiB"):
        check_grid_size((1024, 1024, 1024), 0.01, 1000, "sim.grid_shape")
    check_grid_size((10, 10, 10), 0.01, 1000, "sim.grid_shape")
    with pytest.raises(SimulationError, match="1,001 nodes"):
        check_grid_size((7, 11, 13), 0.01, 1000, "sim.grid_shape")


def test_grid_footprint_counts_every_buffer_by_its_bytes():
    """nbytes: a single-field grid holds (p, m) 16 B and v 12 B per node; a multi-field grid adds a 4-byte
    owner word per node and its pool (4-byte key per row, 4-byte owner and (p, m) + v per extra slot,
    4-byte band mass per slot)."""
    n = 6 * 7 * 8
    single = Grid((0.0, 0.0, 0.0), 0.1, (6, 7, 8), "cpu")
    assert single.nbytes == n * 28
    for slots in (2, 3):
        multi = Grid((0.0, 0.0, 0.0), 0.1, (6, 7, 8), "cpu", slots=slots)
        c = multi.capacity
        extra = c * (slots - 1)
        assert multi.nbytes == (n + extra) * 28 + n * 4 + c * 4 + extra * 4 + c * slots * 4


def test_grid_needs_five_nodes_per_axis():
    """Every axis needs at least 5 nodes (the stencil and the walls): 5 is accepted, 4 refused."""
    Grid((0.0, 0.0, 0.0), 0.1, (5, 5, 5), "cpu")
    with pytest.raises(SimulationError, match="at least 5 nodes"):
        Grid((0.0, 0.0, 0.0), 0.1, (5, 4, 5), "cpu")
