"""Pinned rule of the resolution note (`capture.resolution.choose`'s `note`), round ten: lengths are stated in
millimetres (metres × 1000) to three significant digits, the cells the thin parts get to one decimal, and the
under-resolved warning is given when the thin parts are thinner than one cell, by the exact ratio, not by the
rounded one the note prints.

The probe is replaced by a fixed measurement (its own rules are pinned in round three), and Δx is chosen so that
a wrong unit factor changes a printed digit: 0.5 m / 50 cells = 10 mm exactly (999 · Δx would print 9.99), and
0.5 m / 64 = 7.8125 mm prints 7.81.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture import resolution
from fracture_gs.capture.resolution import choose
from fracture_gs.config import CaptureConfig
from fracture_gs.io.gaussian_set import GaussianSet

UNDER = (
    ' (under-resolved: they move with their neighbours and cannot break on their own; capture.quality = "fine" or '
    "a GPU resolves more)"
)


def some_gaussians(n=20) -> GaussianSet:
    quats = torch.zeros(n, 4)
    quats[:, 0] = 1.0
    return GaussianSet(torch.rand(n, 3), quats, torch.full((n, 3), 0.01), torch.full((n,), 0.9), torch.zeros(n, 1, 3))


@pytest.mark.parametrize(
    "thin, tail",
    [
        (0.0, ""),  # not measured: Δx and the cells only
        (0.025, "; its thin parts, ≈ 25 mm thick, get 2.5 cells"),
        (0.01, "; its thin parts, ≈ 10 mm thick, get 1.0 cells"),  # exactly one cell: resolved
        (0.00999, "; its thin parts, ≈ 9.99 mm thick, get 1.0 cells" + UNDER),  # 0.999 cells prints 1.0: flagged
        (0.0042, "; its thin parts, ≈ 4.2 mm thick, get 0.4 cells" + UNDER),
    ],
)
def test_the_note_states_millimetres_and_cells_across_the_thin_parts(monkeypatch, thin, tail):
    """capture.cells_across = 50 over 0.5 m: Δx = 0.01 m is written "10 mm"; the thin parts' thickness is written
    in mm to three digits and their cells (thin / Δx) to one decimal; 0.999 cells is under one cell and flagged
    even though it prints as 1.0, while exactly 1.0 is not."""
    monkeypatch.setattr(resolution, "probe", lambda *a, **k: (thin, 0.5))
    res = choose(some_gaussians(), CaptureConfig(cells_across=50), "cpu")
    assert (res.cells, res.dx, res.thin) == (50, 0.01, thin)
    assert res.note == "resolution: Δx = 10 mm, 50 cells across (capture.cells_across)" + tail


def test_the_note_of_a_chosen_resolution_states_its_millimetres():
    """On the CPU at quality "fine" with thin parts of 5 mm (wanting 200 cells) the grid is clamped to the
    quality's 64 cells across 0.5 m: Δx = 7.8125 mm, written 7.81; the 5 mm parts get 0.64 cells, written 0.6,
    and are flagged."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(resolution, "probe", lambda *a, **k: (0.005, 1e-6))
        res = choose(some_gaussians(), CaptureConfig(quality="fine"), "cpu")
    assert (res.cells, res.dx) == (64, 0.5 / 64)
    assert res.note == (
        "resolution: Δx = 7.81 mm, 64 cells across (capture.quality = 'fine' on the CPU); its thin parts, ≈ 5 mm "
        "thick, get 0.6 cells" + UNDER
    )
