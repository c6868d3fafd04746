"""Pinned rules of a captured scene's camera (`capture.scene._camera`), round nine:

- `trainer`: the view's camera stands at its centre and looks along its own axis; the look-at point is the
  fitted object's centre projected onto that axis (an orbit, `render.camera.orbit_degrees`, turns about that
  point, so it must lie at the object's depth), at least 1 mm ahead of the camera when the object is behind it;
  the vertical field of view is 2·atan(h / 2f_y); the panel keeps the view's aspect at the configured width,
  rounded to an even height of at least 16 px.
- `auto`: frames a box that is the object's, widened along x halfway to the room's x ends and lowered to
  0.05·size above the room's floor when that is below the object (never raised), seen from −y, 20° above; the
  configured orbit survives.
- `config`: [render.camera] as written. Every branch leaves capture.camera = "config".

Hand-computed boxes: an object at (0.25, 0.38, 0.35)–(0.75, 0.62, 0.65), size 0.5 m. Unit-level calls.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import torch

from fracture_gs.capture.fit import TrainerCamera
from fracture_gs.capture.scene import _camera
from fracture_gs.capture.transform import SceneTransform
from fracture_gs.config import CameraConfig, SceneConfig

F64 = torch.float64
LO, HI = torch.tensor([0.25, 0.38, 0.35], dtype=F64), torch.tensor([0.75, 0.62, 0.65], dtype=F64)


def view(width: int = 800, height: int = 400) -> TrainerCamera:
    """A view at (0, −2, 0) looking along +y (OpenCV axes: x right, y down, z forward), f = 500 px."""
    R = torch.tensor([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]], dtype=F64)  # columns: x, y (down), z
    return TrainerCamera(torch.tensor([0.0, -2.0, 0.0], dtype=F64), R, 500.0, 500.0, width, height, "front")


def config(camera: str, width: int = 320) -> SceneConfig:
    cfg = SceneConfig()
    cfg.scene = "s.ply"
    cfg.capture.camera, cfg.capture.view, cfg.capture.size = camera, 0, 0.5
    cfg.render.width, cfg.render.height = width, 480
    return cfg


def trainer(lo, hi, cam: TrainerCamera | None = None, width: int = 320) -> SceneConfig:
    cfg = config("trainer", width)
    fit = SceneTransform(1.0, torch.eye(3, dtype=F64), torch.zeros(3, dtype=F64))
    lo, hi = torch.tensor(lo, dtype=F64), torch.tensor(hi, dtype=F64)
    _camera(cfg, [cam or view()], fit, lo, hi, lo - 1, hi + 1, [], Path("cameras.json"))
    return cfg


@pytest.mark.parametrize(
    "lo, hi, target_y",
    [
        ((1.0, 3.0, 0.5), (2.0, 4.0, 1.5), 3.5),  # centre (1.5, 3.5, 1): 5.5 m ahead of the camera
        ((-4.0, -1.0, 2.0), (-2.0, 0.0, 6.0), -0.5),  # centre (−3, −0.5, 4): 1.5 m ahead
        ((1.0, -9.0, 0.5), (2.0, -7.0, 1.5), -1.999),  # centre 6 m behind the camera: 1 mm ahead
    ],
)
def test_the_trainer_camera_looks_at_the_object_centre_depth_along_its_axis(lo, hi, target_y):
    """The camera at (0, −2, 0) looking along +y keeps its position and direction; its look-at point is the object
    centre's depth along +y (centre y + 2, or 1 mm when the object is behind it), so the target is (0, y, 0) with
    y = 3.5 for a centre at y 3.5 and −0.5 for one at −0.5, whatever the centre's x and z."""
    cam = trainer(lo, hi).render.camera
    assert cam.eye == (0.0, -2.0, 0.0)
    assert cam.target[0] == 0.0 and cam.target[2] == 0.0
    assert cam.target[1] == pytest.approx(target_y, abs=1e-12)
    assert cam.up == (0.0, 0.0, 1.0)
    assert cam.fov_deg == pytest.approx(math.degrees(2 * math.atan(400 / (2 * 500))))  # 43.60°


@pytest.mark.parametrize(
    "width, size, height", [(320, (800, 400), 160), (324, (800, 400), 162), (100, (800, 80), 16), (64, (4, 3), 48)]
)
def test_the_trainer_panel_keeps_the_view_aspect_even_and_at_least_16(width, size, height):
    """height = width·h/w made even, at least 16: 320 at 2:1 → 160; 324 at 2:1 → 162 (even, kept); 100 at 10:1
    → 10, raised to 16; 64 at 4:3 → 48."""
    cfg = trainer(LO.tolist(), HI.tolist(), view(*size), width)
    assert (cfg.render.width, cfg.render.height) == (width, height)
    assert cfg.capture.camera == "config"


def auto(room_lo, room_hi, orbit: float = 0.0):
    cfg = config("auto", 640)
    cfg.render.camera.orbit_degrees = orbit
    notes = []
    room_lo, room_hi = torch.tensor(room_lo, dtype=F64), torch.tensor(room_hi, dtype=F64)
    _camera(cfg, [], None, LO.clone(), HI.clone(), room_lo, room_hi, notes)
    return cfg, notes


@pytest.mark.parametrize(
    "room_z, target",
    [
        (0.1, (0.525, 0.5, 0.3875)),  # floor room at 0.1: framed down to 0.1 + 0.025 = 0.125 (below 0.35)
        (0.34, (0.525, 0.5, 0.5)),  # 0.34 + 0.025 = 0.365 lies above the object's bottom: z stays 0.35–0.65
    ],
)
def test_the_auto_camera_frames_the_object_half_the_x_room_and_the_floor(room_z, target):
    """Room (0, 0.2, z)–(1.1, 0.8, 0.7) around the object: the framed box reaches halfway to the room's x ends
    (0.125 to 0.925), keeps the object's y (0.38–0.62, not the room's), and reaches down to 0.05·size over the
    room's bottom when that is lower than the object (z 0.125) else keeps the object's bottom; the camera looks
    at the box's centre from −y, 20° above, the eye on that line."""
    cfg, notes = auto((0.0, 0.2, room_z), (1.1, 0.8, 0.7))
    cam = cfg.render.camera
    assert cam.target == pytest.approx(target, abs=1e-12)
    d = torch.tensor(cam.eye, dtype=F64) - torch.tensor(cam.target, dtype=F64)
    e = math.radians(20.0)
    assert (d / d.norm()).tolist() == pytest.approx([0.0, -math.cos(e), math.sin(e)], abs=1e-12)
    assert (cam.up, cam.fov_deg) == ((0.0, 0.0, 1.0), 40.0)
    assert notes == ["camera: frames the object from the front, 20° above"]
    assert cfg.capture.camera == "config"


def test_the_auto_camera_stands_back_by_the_framing_distance_of_that_box():
    """For the box (0.125, 0.38, 0.125)–(0.925, 0.62, 0.65) on a 640 × 480 panel (40° vertical field): the 0.8 m
    width with its 15 % margin needs 0.46 / (tan 20° · 4/3) = 0.9479 m, more than the height's 0.9091 m; plus
    the box's depth seen from 20° above (0.12 cos 20° + 0.2625 sin 20° = 0.2025 m): 1.1504 m from the centre."""
    cam = auto((0.0, 0.2, 0.1), (1.1, 0.8, 0.7))[0].render.camera
    d = torch.tensor(cam.eye, dtype=F64) - torch.tensor(cam.target, dtype=F64)
    assert float(d.norm()) == pytest.approx(1.15042, abs=1e-5)


def test_the_auto_camera_keeps_the_configured_orbit():
    """An orbit set in [render.camera] (here 90°) survives the automatic framing."""
    assert auto((0.0, 0.2, 0.1), (1.1, 0.8, 0.7), orbit=90.0)[0].render.camera.orbit_degrees == 90.0


def test_a_config_camera_is_kept_as_written():
    """capture.camera = "config": the [render.camera] written in the config is drawn unchanged."""
    cfg = config("config")
    written = CameraConfig(eye=(1.0, 2.0, 3.0), target=(0.0, 0.5, 0.0), up=(0.0, 1.0, 0.0), fov_deg=55.0)
    cfg.render.camera = CameraConfig(**vars(written))
    notes = []
    _camera(cfg, [], None, LO, HI, LO - 1, HI + 1, notes)
    assert cfg.render.camera == written and cfg.render.height == 480
    assert notes == ["camera: [render.camera] as written"] and cfg.capture.camera == "config"
