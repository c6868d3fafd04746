"""Pinned rule of the particle budget in the automatic resolution (`capture.resolution.choose`), round eight: when
the fill's 8 particles per solid cell at the wanted cells across exceed the quality's budget, the grid is
coarsened to the MOST cells c whose 8 · fraction · c³ particles fit the budget (≤, an exact fit fits), never
below the quality's fewest cells, and never finer than wanted.

The probe is replaced by the numbers it would return: a solid fraction is n / 128³ for n solid probe voxels,
so 8 · fraction · c³ is exact in float64 and an exact fit is a hand computation: with n = 240 000, 8 · n · 32³
/ 128³ = 30 000, the CPU default budget, to the last bit. The cube root of 30 000 · 128³ / (8 · 240 000) =
32 768 is 31.999… in floating point: the coarsening that took it as the answer picked 31 cells where 32 fit.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture import resolution
from fracture_gs.capture.resolution import choose
from fracture_gs.config import CaptureConfig
from fracture_gs.io.gaussian_set import GaussianSet

PROBE = 128**3  # voxels of the thickness probe's cube
SIZE = 0.5  # m, the default capture.size


def some_gaussians(n=20) -> GaussianSet:
    quats = torch.zeros(n, 4)
    quats[:, 0] = 1.0
    return GaussianSet(torch.rand(n, 3), quats, torch.full((n, 3), 0.01), torch.full((n,), 0.9), torch.zeros(n, 1, 3))


def cells_for(monkeypatch, wanted: int, solid_voxels: int, quality: str = "default", device: str = "cpu") -> int:
    """The cells `choose` takes when the thin parts want `wanted` cells across (2 · size / thin rounded up) and
    the probe found `solid_voxels` of its 128³ voxels solid."""
    thin = 2 * SIZE / (wanted - 0.5)  # 2 · size / thin = wanted − 0.5, rounded up: wanted
    monkeypatch.setattr(resolution, "probe", lambda *a, **k: (thin, solid_voxels / PROBE))
    return choose(some_gaussians(), CaptureConfig(quality=quality), device).cells


@pytest.mark.parametrize(
    "quality, device, wanted, solid, cells",
    [
        ("default", "cpu", 37, 240_000, 32),  # 8 · 240 000 · 32³ / 128³ = 30 000: fits exactly (it picked 31)
        ("default", "cpu", 44, 240_000, 32),
        ("default", "cpu", 37, 240_001, 31),  # 30 000.125 at 32: over by one eighth of a particle
        ("draft", "cpu", 24, 512_000, 16),  # 8 · 512 000 · 16³ / 128³ = 8 000, the draft budget
        ("default", "cuda:0", 74, 600_000, 64),  # 8 · 600 000 · 64³ / 128³ = 600 000
        ("fine", "cuda:0", 113, 524_288, 100),  # 8 · 524 288 · 100³ / 128³ = 2 000 000
        ("fine", "cuda:0", 226, 65_536, 200),  # 8 · 65 536 · 200³ / 128³ = 2 000 000
    ],
)
def test_the_budget_keeps_the_most_cells_that_fit_it_exactly(monkeypatch, quality, device, wanted, solid, cells):
    """8 particles per solid cell at c cells across are 8 · (n / 128³) · c³; an exact fit (equal to the budget)
    fits, one particle's fraction more does not: the chosen cells are the largest c with 8 · n · c³ / 128³ ≤
    the quality's budget, from any wanted count above it, on the CPU and on a GPU."""
    got = cells_for(monkeypatch, wanted, solid, quality, device)
    assert got == cells
    budget = resolution.BUDGETS["cuda" if device.startswith("cuda") else "cpu"][quality][2]
    assert 8 * solid * cells**3 <= budget * PROBE < 8 * solid * (cells + 1) ** 3  # integers: exact


@pytest.mark.parametrize(
    "wanted, solid, cells",
    [
        (30, 240_000, 30),  # under the budget already (8 · 240 000 · 30³ / 128³ = 24 719): as wanted
        (32, 240_000, 32),  # exactly the budget: as wanted
        (44, 0, 44),  # an empty probe (no solid, nothing to budget): the wanted cells, no division by zero
        (44, PROBE, 20),  # a solid cube: 8 · 20³ = 64 000 > 30 000, but 20 is the default quality's fewest
        (44, 1_000_000, 20),  # fits 19 cells (8 · 10⁶ · 19³ / 128³ = 26 165; 20³ gives 30 518): the fewest, 20
    ],
)
def test_the_budget_never_refines_and_never_goes_below_the_fewest_cells(monkeypatch, wanted, solid, cells):
    """Coarsening only: a wanted count within the budget (also exactly at it) is kept; with nothing solid the
    budget does not apply; a budget that fits fewer cells than the quality's fewest (20 on the CPU default)
    gives the fewest."""
    assert cells_for(monkeypatch, wanted, solid) == cells
