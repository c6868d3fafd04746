"""Pinned rules of the automatic resolution (`capture.resolution`), round three: the thickness probe's voxels
are size/128, the thin parts are the 10th percentile (linear interpolation) of the medial thickness 2·peak − 1
voxels, the solid fraction is over the 128³ probe cube; `choose` takes Δx for two cells across the thin parts,
clamps it to the quality's cells and coarsens to the most cells whose 8 particles per solid cell fit the
budget (never below the fewest cells).

The probe's solid is given (the voxeliser `solid_voxels` is replaced by hand-built slabs whose medial thickness
is known), so every number below is a hand computation.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture import resolution
from fracture_gs.capture.resolution import choose, probe
from fracture_gs.config import CaptureConfig
from fracture_gs.io.gaussian_set import GaussianSet


def some_gaussians(n=20) -> GaussianSet:
    quats = torch.zeros(n, 4)
    quats[:, 0] = 1.0
    return GaussianSet(torch.rand(n, 3), quats, torch.full((n, 3), 0.01), torch.full((n,), 0.9), torch.zeros(n, 1, 3))


def slabs(thin: int, thick: int, side: int = 4) -> torch.Tensor:
    """`thin` sheets 1 voxel thick and `thick` slabs 5 voxels thick, each spanning the whole side × side cross
    section, stacked along z with one empty layer between and around them. Every sheet's voxels are medial
    with thickness 1 (depth 1); each slab's middle layer is (depth 3: thickness 2·3 − 1 = 5); so the medial
    thicknesses are side² ones per sheet and side² fives per slab."""
    layers = [False]
    for k in [1] * thin + [5] * thick:
        layers += [True] * k + [False]
    z = torch.tensor(layers)
    return z[None, None, :].expand(side, side, len(layers)).clone()


@pytest.mark.parametrize(
    "thin, thick, voxels",
    [
        (1, 9, 4.6),  # 16 ones then 144 fives: q = 0.1·159 = 15.9 → 1 + 0.9·(5 − 1)
        (1, 8, 1.0),  # 16 of 144 are ones (11 %): q = 14.3 lies among the ones
        (1, 10, 5.0),  # 16 of 176 are ones (9 %): q = 17.5 lies among the fives
        (0, 3, 5.0),
        (3, 0, 1.0),
    ],
)
def test_thin_parts_are_the_10th_percentile_of_the_medial_thickness(monkeypatch, thin, thick, voxels):
    """The probe voxelises at h = size / 128 and returns the 10th percentile (linear interpolation) of the
    medial thicknesses times h, and the solid's voxel count over 128³: with one sheet and nine slabs (10 % of
    the medial surface thin) that is 4.6 voxels; with 11 % thin it is 1 voxel (the sheet), with 9 % thin 5
    voxels (the slabs)."""
    seen = {}

    def fake_solid(gs, h, **kw):
        seen["h"] = h
        return slabs(thin, thick)

    monkeypatch.setattr(resolution, "solid_voxels", fake_solid)
    size = 0.64
    t, fraction = probe(some_gaussians(), size, 0.2, 0.01, 1)
    h = size / 128
    assert seen["h"] == pytest.approx(h, rel=1e-15)
    assert t == pytest.approx(voxels * h, rel=1e-9)
    assert fraction == pytest.approx(16 * (thin + 5 * thick) / 128**3, rel=1e-12)


def test_an_empty_solid_measures_nothing(monkeypatch):
    """No solid voxel: thickness 0 and fraction 0 (the caller then takes the quality's most cells)."""
    monkeypatch.setattr(resolution, "solid_voxels", lambda gs, h, **kw: torch.zeros(4, 4, 4, dtype=torch.bool))
    assert probe(some_gaussians(), 0.5, 0.2, 0.01, 1) == (0.0, 0.0)


@pytest.mark.parametrize(
    "thin, fraction, cells",
    [
        (0.5 / 16, 1e-6, 32),  # two cells across 1/16 of the size: 32, between 20 and 44
        (0.5 / 5, 1e-6, 20),  # wants 10: raised to the fewest, 20
        (0.5 / 30, 1e-6, 44),  # wants 60: cut to the most, 44
        (0.0, 1e-6, 44),  # not measured: the most
        (0.5 / 30, 0.1, 33),  # 8·0.1·44³ = 68 147 > 30 000: coarsened to 33 (8·0.1·33³ = 28 750; 34 would not fit)
        (0.5 / 30, 1.0, 20),  # 8·20³ = 64 000 > 30 000 but 20 is the fewest: kept
    ],
)
def test_choose_takes_two_cells_across_the_thin_parts_within_the_budget(monkeypatch, thin, fraction, cells):
    """CPU, quality `default` (20 to 44 cells across, 30 000 particles), size 0.5 m: cells = ceil(2·size/thin)
    clamped to [20, 44], then coarsened while 8 particles per solid cell (fraction·cells³ solid cells) exceed the
    budget, never below 20; Δx = size / cells and the budget is reported."""
    monkeypatch.setattr(resolution, "probe", lambda *a, **k: (thin, fraction))
    res = choose(some_gaussians(), CaptureConfig(), "cpu")
    assert res.cells == cells
    assert res.dx == pytest.approx(0.5 / cells, rel=1e-12)
    assert res.budget == 30_000 and res.thin == thin


def test_given_cells_across_are_used_as_given_and_the_note_says_so(monkeypatch):
    """capture.cells_across = 40 is used as written, whatever the probe measured (Δx = 0.5/40 = 12.5 mm), with
    the quality's budget still reported; the note names the key and the cells the thin parts get."""
    monkeypatch.setattr(resolution, "probe", lambda *a, **k: (0.5 / 16, 0.5))
    res = choose(some_gaussians(), CaptureConfig(cells_across=40), "cpu")
    assert (res.cells, res.budget) == (40, 30_000)
    assert res.dx == pytest.approx(0.0125, rel=1e-12)
    assert res.note == (
        "resolution: Δx = 12.5 mm, 40 cells across (capture.cells_across); its thin parts, ≈ 31.2 mm thick, "
        "get 2.5 cells"
    )


def test_note_flags_thin_parts_under_one_cell(monkeypatch):
    """Thin parts thinner than a cell (5 mm at Δx = 0.5/44 = 11.4 mm: 0.44 cells) are reported as under-resolved
    with the way out; measured but resolved parts are not; an unmeasured object's note states only Δx."""
    monkeypatch.setattr(resolution, "probe", lambda *a, **k: (0.005, 1e-6))
    under = choose(some_gaussians(), CaptureConfig(), "cpu")
    assert under.note == (
        "resolution: Δx = 11.4 mm, 44 cells across (capture.quality = 'default' on the CPU); its thin parts, "
        "≈ 5 mm thick, get 0.4 cells (under-resolved: they move with their neighbours and cannot break on their "
        'own; capture.quality = "fine" or a GPU resolves more)'
    )
    monkeypatch.setattr(resolution, "probe", lambda *a, **k: (0.0, 1e-6))
    assert choose(some_gaussians(), CaptureConfig(quality="fine"), "cuda:0").note == (
        "resolution: Δx = 1.95 mm, 256 cells across (capture.quality = 'fine' on the GPU)"
    )


def test_thin_parts_of_exactly_one_cell_are_resolved(monkeypatch):
    """Thin parts exactly one cell thick (31.25 mm at 16 cells across 0.5 m) get 1.0 cells and are not flagged:
    only fewer than one cell is under-resolved."""
    monkeypatch.setattr(resolution, "probe", lambda *a, **k: (0.03125, 1e-6))
    res = choose(some_gaussians(), CaptureConfig(cells_across=16), "cpu")
    assert res.note == (
        "resolution: Δx = 31.2 mm, 16 cells across (capture.cells_across); its thin parts, ≈ 31.2 mm thick, "
        "get 1.0 cells"
    )
