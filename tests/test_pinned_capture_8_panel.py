"""Pinned rule of the video panel size of a captured scene (`capture.scene.resolve`), round eight:
`capture.panel = "auto"` (the default) sets [render] width × height to 640 × 480 on the CPU and 1280 × 720 on a
GPU, and writes "config" so a rerun of the written config keeps that size; `capture.panel = "config"` keeps the
[render] width and height as written, on either device.

A 400-Gaussian trainer-like PLY; the resolution step is replaced by a fixed 8 cells (its own rules are pinned
elsewhere) and nothing is filled, so each resolve takes a fraction of a second.
"""

from __future__ import annotations

import pytest
import torch
from trainer_ply import write_trainer_ply

from fracture_gs.capture import scene
from fracture_gs.capture.resolution import Resolution
from fracture_gs.io.config import config_from_dict


@pytest.fixture(scope="module")
def small_ply(tmp_path_factory):
    ply, _ = write_trainer_ply(tmp_path_factory.mktemp("panel"), n=400, floaters=0, far=0)
    return ply


@pytest.mark.parametrize(
    "panel, device, size",
    [
        ("auto", "cpu", (640, 480)),
        ("auto", "cuda:0", (1280, 720)),
        ("config", "cpu", (320, 200)),
        ("config", "cuda:0", (320, 200)),
    ],
)
def test_the_panel_is_sized_for_the_device_unless_the_config_sizes_it(monkeypatch, small_ply, panel, device, size):
    """[render] 320 × 200 in the config: panel "auto" replaces it with the device's size (640 × 480 on the CPU,
    1280 × 720 on a GPU), panel "config" keeps it; either way the resolved config says panel = "config"."""
    monkeypatch.setattr(scene, "choose_resolution", lambda obj, cap, device: Resolution(8, cap.size / 8, 0.0, "r", 300))
    if device.startswith("cuda"):  # the panel rule alone: `resolve` checks the device exists, and nothing else uses it
        monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
        monkeypatch.setattr(torch.cuda, "device_count", lambda: 1)
    doc = {
        "extends": "capture",
        "scene": str(small_ply),
        "fill_interior": False,
        "render": {"width": 320, "height": 200},
        "capture": {"panel": panel, "load": "none", "ground": "none", "outlier_neighbours": 0},
    }
    cfg = scene.resolve(config_from_dict(doc), device).cfg
    assert (cfg.render.width, cfg.render.height) == size
    assert cfg.capture.panel == "config"
