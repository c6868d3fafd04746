"""The slot storage's active box and pool expectation (`sim.grid.slots.SlotStorage`), against hand values:

- `fit` takes the particles' bounding box in nodes (floor of (x − origin)/Δx; the upper end one node further, hi
  exclusive) and widens it on every side by the stencil's 3 nodes, the travel rounded UP to whole nodes, and the
  runner's slack, clipped to the grid; the grid is zeroed when, and only when, the box changes;
- `reset(bands)` (a latch) expects at least 4 pool rows per band particle plus one per 64 particles, never fewer
  than before, and hands the whole grid back to the grid work.

A 32³ grid, Δx = 1/32 m, origin 0; 512 particles."""

import pytest
import torch
from simutil import block, config, particles

from fracture_gs import sim as S

DX = 1 / 32


@pytest.fixture(scope="module")
def sim():
    x, vol = block((0.4, 0.4, 0.4), (0.6, 0.6, 0.6), 0.025)
    return S.Simulator(config(32), particles(x, vol), device="cpu")


@pytest.mark.parametrize(
    "lower, upper, travel, slack, box",
    [
        ((0.5, 0.5, 0.5), (0.5, 0.5, 0.5), 0.0, 0, (13, 13, 13, 20, 20, 20)),
        ((0.5, 0.5, 0.5), (0.5, 0.5, 0.5), 1.5 * DX, 1, (10, 10, 10, 23, 23, 23)),
        ((0.5, 0.5, 0.5), (0.5, 0.5, 0.5), 2.0 * DX, 0, (11, 11, 11, 22, 22, 22)),
        ((0.0, 0.05, 0.9), (0.1, 0.5, 0.99), 0.0, 0, (0, 0, 25, 7, 20, 32)),
    ],
)
def test_the_active_box_is_the_particles_box_widened_by_stencil_travel_and_slack(sim, lower, upper, travel, slack, box):
    """Bounds → nodes [floor, floor + 1) widened by 3 + ceil(travel/Δx) + slack per side, clipped to [0, 32)."""
    sim.slots.fit(torch.tensor(lower), torch.tensor(upper), travel, slack)
    assert sim.slots.box == box
    assert sim.grid.box == box


def test_the_grid_is_zeroed_when_the_box_changes_and_only_then(sim):
    """Velocities preset to 5: a fit to a new box zeroes them; the same fit again leaves them."""
    lo, hi = torch.tensor([0.3, 0.3, 0.3]), torch.tensor([0.6, 0.6, 0.6])
    sim.slots.fit(lo, hi, 0.0, 0)
    sim.grid.vel.fill_(5.0)
    sim.slots.fit(lo, hi, 0.0, 0)
    assert bool((sim.grid.vel == 5.0).all()), "same box: kept"
    sim.slots.fit(lo, hi, 0.0, 2)
    assert not bool(sim.grid.vel.any()), "new box: zeroed"


def test_a_latch_expects_four_rows_per_band_particle_and_one_per_64_particles(sim):
    """512 particles (8 rows). From 10 expected rows: 5 band particles → 4·5 + 8 = 28; then 0 → still 28 (never
    fewer); from 100, 3 band particles (20) keep 100. The grid work takes the whole grid again."""
    s = sim.slots
    assert len(sim.particles) == 512
    s.pool_rows = 10
    s.fit(torch.tensor([0.5] * 3), torch.tensor([0.5] * 3), 0.0, 0)
    s.reset(5)
    assert s.pool_rows == 28 and s.box == (0, 0, 0, 32, 32, 32)
    s.reset(0)
    assert s.pool_rows == 28
    s.pool_rows = 100
    s.reset(3)
    assert s.pool_rows == 100
    assert not bool(s.solo.any())
