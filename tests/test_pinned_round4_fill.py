"""`capture.scene._fill`, which spacing's interior fill a captured object keeps. It fills at Δx/2, then Δx, then
2Δx, and stops at the first whose shell encloses at least a quarter of the solid it bounds (0.25 itself is
enough); otherwise it keeps the one that enclosed most (the first of equals, i.e. the finest) if that is a closed
surface (≥ FILL_WARNING = 0.1, included), else the finest fill. Fill particles are then drawn at most Δx/4 wide,
surface Gaussians keep their size, and the note says which case it was. `assets.fill_interior` is replaced by a
stand-in that reports a chosen enclosed fraction per spacing and records what it was asked for."""

from __future__ import annotations

import pytest
import torch

from fracture_gs import assets
from fracture_gs.capture import scene as S
from fracture_gs.config import CaptureConfig
from fracture_gs.io.gaussian_set import GaussianSet

DX = 0.02


def _object(n=4):
    quats = torch.zeros(n, 4)
    quats[:, 0] = 1.0
    return GaussianSet(torch.rand(n, 3), quats, torch.full((n, 3), 0.05), torch.full((n,), 0.9), torch.zeros(n, 1, 3))


def _fake_fill(monkeypatch, fractions):
    """fill_interior stand-in: at the i-th call, the object plus 2 + i interior particles of size 0.05 m, and the
    stats of enclosed fraction fractions[i]."""
    calls = []

    def fake(gs, spacing=None, max_particles=0, threshold=0.0, min_opacity=0.0, closing=0, stats=None, **kw):
        i = len(calls)
        calls.append(dict(spacing=spacing, max_particles=max_particles, threshold=threshold,
                          min_opacity=min_opacity, closing=closing, **kw))  # fmt: skip
        k = 2 + i
        inner = _object(k)
        out = GaussianSet(
            torch.cat([gs.means, inner.means]),
            torch.cat([gs.quats, inner.quats]),
            torch.cat([gs.scales, inner.scales]),
            torch.cat([gs.opacities, inner.opacities]),
            torch.cat([gs.sh, inner.sh]),
            interior=torch.cat([torch.zeros(len(gs), dtype=torch.bool), torch.ones(k, dtype=torch.bool)]),
        )
        stats.update(added=k, spacing=spacing, enclosed_fraction=fractions[i])
        return out

    monkeypatch.setattr(assets, "fill_interior", fake)
    return calls


def _run(monkeypatch, fractions):
    calls = _fake_fill(monkeypatch, fractions)
    notes = []
    cap = CaptureConfig(fill_threshold=0.3, fill_closing=2, min_opacity=0.07, seal_bottom=True)
    out = S._fill(_object(), cap, DX, notes, 1234)
    return out, calls, notes


@pytest.mark.parametrize(
    "fractions, tried, kept",
    [
        ((0.25, 0.9, 0.9), 1, 0),  # exactly a quarter at Δx/2: done
        ((0.6, 0.9, 0.9), 1, 0),
        ((0.2, 0.3, 0.9), 2, 1),  # the first past a quarter, not the best
        ((0.05, 0.2, 0.15), 3, 1),  # none past a quarter: the one that enclosed most
        ((0.05, 0.1, 0.02), 3, 1),  # FILL_WARNING itself is a closed surface
        ((0.15, 0.15, 0.15), 3, 0),  # equals: the finest
        ((0.05, 0.09, 0.08), 3, 0),  # all open: the finest
    ],
)
def test_the_first_spacing_enclosing_a_quarter_wins_else_the_best_closed_else_the_finest(
    monkeypatch, fractions, tried, kept
):
    """Which fills are made (Δx/2, Δx, 2Δx in that order, stopping at the first ≥ 0.25) and which is kept: the
    kept fill is recognisable by its count of interior particles (2 + its index)."""
    out, calls, notes = _run(monkeypatch, fractions)
    assert [c["spacing"] for c in calls] == pytest.approx([DX / 2, DX, 2 * DX][:tried], rel=1e-12)
    assert int(out.interior.sum()) == 2 + kept
    enclosed = fractions[kept]
    if enclosed >= S.FILL_WARNING:
        assert notes == [
            f"interior: filled with {2 + kept} particles at {1e3 * [DX / 2, DX, 2 * DX][kept]:.3g} mm spacing (the "
            f"surface encloses {100 * enclosed:.0f} % of the solid it bounds)"
        ]
    else:
        assert notes[0].startswith(f"interior: the surface is open at {1e3 * DX / 2:.3g} mm voxels (it encloses ")
        assert "raise capture.fill_closing (now 2) or lower capture.fill_threshold (now 0.3)" in notes[0]


def test_every_fill_gets_the_capture_settings_and_the_particle_budget(monkeypatch):
    """Each call passes the budget as max_particles and capture.fill_threshold, min_opacity, fill_closing and
    seal_bottom through unchanged."""
    _, calls, _ = _run(monkeypatch, (0.0, 0.0, 0.0))
    assert len(calls) == 3
    for c in calls:
        assert (c["max_particles"], c["threshold"], c["min_opacity"], c["closing"], c["seal_bottom"]) == (
            1234,
            0.3,
            0.07,
            2,
            True,
        )


def test_fill_particles_are_drawn_at_most_a_quarter_cell_wide_and_surface_ones_keep_their_size(monkeypatch):
    """The stand-in's interior particles are 0.05 m wide: kept ones come back at Δx/4 = 5 mm on every axis; the
    object's own Gaussians (also 0.05 m) are unchanged."""
    out, _, _ = _run(monkeypatch, (0.5, 0.0, 0.0))
    assert torch.equal(out.scales[out.interior], torch.full((2, 3), 0.25 * DX))
    assert torch.equal(out.scales[~out.interior], torch.full((4, 3), 0.05))
