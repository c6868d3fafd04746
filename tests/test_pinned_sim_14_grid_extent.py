"""The grid's extent checks (`sim.grid.domain`) that the pinned grid tests leave out, against hand values:

- `sim.grid` other than 'explicit' or 'auto' is refused by name; an automatic grid over non-finite particle
  bounds is refused with the fix (before any arithmetic on inf or NaN);
- grid bounds only ever enlarge an automatic grid: particles outside the bounds stay covered;
- a CUDA device must have the grid's buffers free with a 10 % reserve: up to 0.9 × the free memory is accepted,
  a byte more is refused in one sentence with both sizes in GiB; CPU grids are not checked."""

import pytest
import torch

from fracture_gs.config import SimConfig
from fracture_gs.errors import SimulationError
from fracture_gs.sim.grid.domain import check_device_memory, fit_grid


def test_an_unknown_grid_mode_and_non_finite_bounds_are_refused():
    """grid = 'fixed' names itself and the two choices; a NaN position under grid = 'auto' names the fix."""
    with pytest.raises(SimulationError, match=r"^sim.grid must be 'explicit' or 'auto', not 'fixed'$"):
        fit_grid(SimConfig(grid="fixed", dx=0.1), torch.zeros(2, 3))
    x = torch.tensor([[0.0, 0.0, 0.0], [float("nan"), 1.0, 1.0]])
    with pytest.raises(SimulationError, match=r"bounds are not finite; remove NaN or inf positions$"):
        fit_grid(SimConfig(grid="auto", dx=0.1, grid_margin=0.0), x)


def test_grid_bounds_never_shrink_an_automatic_grid():
    """Particles spanning [0, 2] on x with bounds [0.5, 1]³, no margin, no walls (pad 2Δx = 0.125): x still spans
    [−0.125, 2.125] (the particles win), y and z [0.375, 1.125] (the bounds win over the particles at 0.5 … 1)."""
    x = torch.tensor([[0.0, 0.5, 0.5], [2.0, 1.0, 1.0]])
    cfg = SimConfig(grid="auto", dx=1 / 16, grid_margin=0.0, wall_cells=0, grid_bounds=((0.5,) * 3, (1.0,) * 3))
    origin, dx, shape = fit_grid(cfg, x)
    assert origin == (-0.125, 0.375, 0.375)
    assert shape == (37, 13, 13)


def test_a_cuda_grid_needs_its_buffers_free_with_a_ten_percent_reserve(monkeypatch):
    """With 10 GiB free on 'cuda:1': 9 GiB (0.9 × free) is accepted; 9 GiB + 1 byte is refused, naming the shape,
    ≈ 9.00 GiB needed and 10.00 GiB free; on 'cpu' nothing is asked."""
    seen = []

    def free(device):
        seen.append(str(device))
        return 10 * 2**30, 80 * 2**30

    monkeypatch.setattr(torch.cuda, "mem_get_info", free)
    check_device_memory(9 * 2**30, "cuda:1", (10, 20, 30))
    with pytest.raises(SimulationError) as err:
        check_device_memory(9 * 2**30 + 1, "cuda:1", (10, 20, 30))
    want = "a 10×20×30 grid needs ≈ 9.00 GiB but cuda:1 has 10.00 GiB free; use a coarser grid (raise sim.dx)"
    assert str(err.value).startswith(want), str(err.value)
    assert seen == ["cuda:1", "cuda:1"]
    check_device_memory(10**15, "cpu", (10, 20, 30))
    assert len(seen) == 2
