"""Pinned rules of the trainer camera in a resolved capture (`capture.scene._camera`), round eight:
`capture.camera = "trainer"` draws view capture.view of cameras.json, which must be one of its views 0..n−1
(−1 is not "the last one", as a Python index would read it); the SceneError names the scene, the value and the
views there are. A valid view sets the panel's height from the view's aspect ratio (at the configured width, even,
at least 16), points the camera along the view, notes which view it is, and the config then says "config".
"""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from fracture_gs.capture.fit import TrainerCamera
from fracture_gs.capture.scene import _camera
from fracture_gs.capture.transform import SceneTransform
from fracture_gs.config import SceneConfig
from fracture_gs.errors import SceneError

F64 = torch.float64


def views(n: int) -> list[TrainerCamera]:
    """n views at x = 0..n−1 on the line y = −2, looking along +y (OpenCV axes: x right, y down, z forward),
    800 × 400 pixels."""
    R = torch.tensor([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]], dtype=F64)  # columns: x, y (down), z
    return [
        TrainerCamera(torch.tensor([float(i), -2.0, 0.0], dtype=F64), R, 500.0, 500.0, 800, 400, f"v{i}")
        for i in range(n)
    ]


def run(view: int, cameras: list[TrainerCamera]):
    cfg = SceneConfig()
    cfg.scene = "s.ply"
    cfg.capture.camera, cfg.capture.view = "trainer", view
    cfg.render.width = 320
    fit = SceneTransform(1.0, torch.eye(3, dtype=F64), torch.zeros(3, dtype=F64))
    lo, hi = torch.tensor([-0.5, -0.5, -0.5], dtype=F64), torch.tensor([0.5, 0.5, 0.5], dtype=F64)
    notes = []
    _camera(cfg, cameras, fit, lo, hi, lo - 1, hi + 1, notes, Path("cameras.json"))
    return cfg, notes


@pytest.mark.parametrize("n, view", [(2, 2), (2, -1), (3, 7), (1, -3), (1, 1)])
def test_a_view_outside_the_file_is_refused_naming_the_views_there(n, view):
    """capture.view must index one of the n views (0..n−1): n itself, anything beyond and any negative view
    are refused in one sentence with the value and the range 0..n−1."""
    with pytest.raises(SceneError) as info:
        run(view, views(n))
    assert str(info.value) == f"s.ply: capture.view = {view} but cameras.json has views 0..{n - 1}."


@pytest.mark.parametrize("n, view", [(2, 0), (2, 1), (3, 2), (1, 0)])
def test_a_view_in_the_file_is_drawn(n, view):
    """The first and the last view are both valid: the camera stands at the view's centre, looks along its
    forward axis (+y) at the depth of the object's centre (2), keeps its up (−y of the camera: +z); the panel
    is 320 × 160 (the view's 2:1 at the configured width); the note names the view; camera becomes "config"."""
    cfg, notes = run(view, views(n))
    cam = cfg.render.camera
    assert cam.eye == (float(view), -2.0, 0.0)
    assert cam.target == (float(view), 0.0, 0.0)
    assert cam.up == (0.0, 0.0, 1.0)
    assert (cfg.render.width, cfg.render.height) == (320, 160)
    assert notes == [f"camera: trainer view {view} (v{view})"]
    assert cfg.capture.camera == "config"


def test_no_cameras_json_is_refused_naming_the_fix():
    """camera = "trainer" with no views found: refused, pointing at capture.cameras_json or camera = "auto"."""
    with pytest.raises(SceneError) as info:
        run(0, [])
    assert str(info.value) == (
        's.ply: capture.camera = "trainer" but no cameras.json was found beside the PLY; set capture.cameras_json '
        'or use capture.camera = "auto".'
    )
