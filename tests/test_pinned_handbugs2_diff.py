"""Hand-written bug campaign, round two: the differentiable solver's grid work (`sim.diff.solver.DiffSimulator`).

- G2P's clamp leaves w − 1 free cells inside the first node and inside the last (w = wall_cells), as the plain
  solver's: 32 nodes at Δx = 1/32 from the origin, w = 2 → [1/32, 30/32] on every axis.
- A frame's active box reaches as far beyond the highest particle's cell as below the lowest one's: at rest and
  without gravity the pad is 5 nodes, so nodes cell_min − 5 … cell_max + 5 on every axis (the stencil's upper
  nodes, base + 2 ≤ cell + 2, lie inside it).
"""

import torch
from simutil import block, config

from fracture_gs.sim.diff.solver import DiffSimulator


def _sim():
    x, _ = block((0.375, 0.4, 0.45), (0.5, 0.55, 0.6), 1 / 64)
    return DiffSimulator(config(32, wall_cells=2, variant="baseline"), x), x


def test_the_clamp_is_as_far_from_the_upper_walls_as_from_the_lower():
    """lower = origin + (w − 1)Δx, upper = origin + (s − w)Δx: 1/32 and 30/32, the same w − 1 = 1 cell inside the first
    node (0) and the last (31/32)."""
    sim, _ = _sim()
    lower, upper = [float(a) for a in sim._lower], [float(a) for a in sim._upper]
    assert lower == [1 / 32] * 3
    assert upper == [30 / 32] * 3


def test_the_active_box_pads_both_sides_of_the_particles_alike():
    """Particles at rest, no gravity: box nodes lo … lo + shape − 1 are cell_min − 5 … cell_max + 5 per axis."""
    sim, x = _sim()
    sim._x = x
    lo, shape = sim._box(torch.zeros_like(x), 0.01)
    cell_min = torch.floor(x.double().min(0).values * 32).long().tolist()
    cell_max = torch.floor(x.double().max(0).values * 32).long().tolist()
    assert list(lo) == [c - 5 for c in cell_min]
    assert [a + s - 1 for a, s in zip(lo, shape)] == [c + 5 for c in cell_max]
