"""Pinned rule of the object/background split of a captured scene (`capture.scene.resolve`), round nine: the
region of interest must hold at least 10 of the Gaussians left after cleaning — 10 is enough, 9 is refused in one
sentence naming the file, the count, the cleaned total and the fix; the note then counts the Gaussians simulated
and the rest of the cleaned ones, kept as a static background (None when there is none).

A 405-Gaussian PLY written in the test: a 10 × 10 × 4 lattice at 0.1 spacing of opaque Gaussians plus 5 faint
floaters that cleaning removes (so the cleaned total, 400, differs from the file's, 405). The resolution step is
replaced by a fixed 8 cells (its own rules are pinned elsewhere) and nothing is filled, so each resolve takes a
fraction of a second.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture import scene
from fracture_gs.capture.resolution import Resolution
from fracture_gs.errors import SceneError
from fracture_gs.io.config import config_from_dict
from fracture_gs.io.gaussian_set import GaussianSet
from fracture_gs.io.ply import save_ply


@pytest.fixture(scope="module")
def lattice_ply(tmp_path_factory):
    i, j, k = torch.meshgrid(torch.arange(10), torch.arange(10), torch.arange(4), indexing="ij")
    solid = 0.1 * torch.stack([i, j, k], -1).reshape(-1, 3).float()  # [400, 3]
    faint = torch.tensor([[5.0, 5.0, 5.0]]) + 0.1 * torch.arange(5.0)[:, None]  # [5, 3]
    means = torch.cat([solid, faint])
    n = len(means)
    quats = torch.zeros(n, 4)
    quats[:, 0] = 1.0
    opacities = torch.cat([torch.full((400,), 0.9), torch.full((5,), 0.001)])
    gs = GaussianSet(
        means=means, quats=quats, scales=torch.full((n, 3), 0.03), opacities=opacities, sh=torch.zeros(n, 16, 3)
    )
    path = tmp_path_factory.mktemp("lattice") / "lattice.ply"
    save_ply(gs, path)
    return path


def resolve(monkeypatch, ply, roi: dict):
    monkeypatch.setattr(scene, "choose_resolution", lambda obj, cap, device: Resolution(8, cap.size / 8, 0.0, "r", 300))
    doc = {
        "extends": "capture",
        "scene": str(ply),
        "fill_interior": False,
        "capture": {"load": "none", "ground": "none", "outlier_neighbours": 0, "up": "+z", **roi},
    }
    return scene.resolve(config_from_dict(doc), "cpu")


def box(nx: int, ny: int) -> dict:
    """A box holding the nx × ny lattice points nearest the origin in the bottom layer (z = 0)."""
    return {"roi": "box", "roi_lower": [-0.05, -0.05, -0.05], "roi_upper": [0.1 * nx - 0.05, 0.1 * ny - 0.05, 0.05]}


def split_note(notes: list) -> str:
    (note,) = [n for n in notes if n.startswith("region of interest")]
    return note


def test_ten_gaussians_in_the_region_are_enough(monkeypatch, lattice_ply):
    """A 2 × 5 patch (10 Gaussians) is simulated; the other 390 of the 400 cleaned ones (the 5 faint floaters
    are gone) are the static background."""
    cap = resolve(monkeypatch, lattice_ply, box(2, 5))
    assert split_note(cap.notes) == (
        "region of interest: box (capture.roi_lower/upper): 10 Gaussians simulated, 390 kept as a static background"
    )
    assert len(cap.background) == 390


def test_nine_gaussians_in_the_region_are_refused(monkeypatch, lattice_ply):
    """A 3 × 3 patch (9 Gaussians) is too little to simulate: one sentence with the count of the 400 cleaned
    Gaussians (not the file's 405) and how to widen the region."""
    with pytest.raises(SceneError) as info:
        resolve(monkeypatch, lattice_ply, box(3, 3))
    assert str(info.value) == (
        f"{lattice_ply}: the region of interest holds 9 of 400 Gaussians; move or widen capture.roi_* "
        '(or set capture.roi = "auto").'
    )


def test_a_region_holding_everything_leaves_no_background(monkeypatch, lattice_ply):
    """roi = "all": every one of the 400 cleaned Gaussians is simulated, 0 are background, and there is no
    background set at all (None, not an empty one)."""
    cap = resolve(monkeypatch, lattice_ply, {"roi": "all"})
    assert (
        split_note(cap.notes)
        == "region of interest: everything: 400 Gaussians simulated, 0 kept as a static background"
    )
    assert cap.background is None
