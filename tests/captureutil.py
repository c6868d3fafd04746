"""Spies on the capture fit's internals for the pinned capture tests: what the ROI's voxeller and torch.quantile
are given, with the real quantile still answering."""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture import fit, scene
from fracture_gs.capture.resolution import Resolution


def voxeller_spy(monkeypatch) -> list:
    """Replace the voxeller by a recorder of (Gaussians given, core_lo, core_hi, h); it returns the core."""
    seen = []

    def connected(x, core_lo, core_hi, h):
        seen.append((x.clone(), core_lo.tolist(), core_hi.tolist(), h))
        return core_lo, core_hi

    monkeypatch.setattr(fit, "auto_roi_connected", connected)
    return seen


def quantile_spy(monkeypatch) -> list:
    """Wrap torch.quantile (the real one still answers) to see the values it is given."""
    seen = []
    real = torch.quantile

    def spy(values, q, *args, **kw):
        seen.append(values.clone())
        return real(values, q, *args, **kw)

    monkeypatch.setattr(torch, "quantile", spy)
    return seen


@pytest.fixture(autouse=True)
def fixed_resolution(monkeypatch):
    """Every capture resolved with 8 cells across its size (`scene.choose_resolution` stubbed): the scene's other
    choices without the resolution search. Autouse in the test modules that import it."""
    monkeypatch.setattr(scene, "choose_resolution", lambda obj, cap, device: Resolution(8, cap.size / 8, 0.0, "r", 300))
