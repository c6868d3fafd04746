"""Pinned rule of the automatic capture camera (`capture.camera.frame_box`), round seventeen: the camera stands
back by the larger of two distances, the one at which the box's width fills the horizontal field
(across / tan(fov_h / 2)) and the one at which its height fills the vertical field (upward / tan(fov_v / 2)), each
with a 15 % margin, plus the box's own depth toward the camera. A box taller than wide is framed by its height, so
every corner stays inside the picture whatever the field of view (earlier tests used fov 90°, where tan = 1
hides a multiplication in place of the division).
"""

from __future__ import annotations

import math

import pytest
import torch

from fracture_gs.capture.camera import frame_box


def test_a_tall_box_is_framed_by_its_height_with_a_15_percent_margin():
    """Hand computation, elevation 0, fov 60°, square image: box [0, 1] × [0, 1] × [0, 4] has half-extents
    (0.5, 0.5, 2); upward = 2 · 1.15 = 2.3, tan 30° = 1/√3, so the eye is 2.3 · √3 + 0.5 (the half depth) from
    the centre (0.5, 0.5, 2) along −y; across (0.575 · √3 ≈ 1.0) is smaller and does not decide."""
    cam = frame_box((0.0, 0.0, 0.0), (1.0, 1.0, 4.0), 100, 100, fov_deg=60.0, elevation_deg=0.0)
    dist = 2.3 * math.sqrt(3.0) + 0.5
    assert cam.target == pytest.approx((0.5, 0.5, 2.0), abs=1e-12)
    assert cam.eye == pytest.approx((0.5, 0.5 - dist, 2.0), abs=1e-12)
    assert cam.fov_deg == 60.0 and cam.up == (0.0, 0.0, 1.0)


def test_a_wide_image_is_framed_by_the_taller_need_and_a_flat_box_by_its_width():
    """fov 40°, elevation 0, image 2:1 (tan_h = 2 · tan 20°): a box 1 wide and 4 tall needs 2.3 / tan 20° (the
    height decides); a box 8 wide and 1 tall needs 4.6 / (2 tan 20°) (the width decides); both plus half the
    depth (0.5)."""
    t = math.tan(math.radians(20.0))
    tall = frame_box((0.0, 0.0, 0.0), (1.0, 1.0, 4.0), 200, 100, fov_deg=40.0, elevation_deg=0.0)
    assert 0.5 - tall.eye[1] == pytest.approx(2.3 / t + 0.5, rel=1e-12)
    flat = frame_box((0.0, 0.0, 0.0), (8.0, 1.0, 1.0), 200, 100, fov_deg=40.0, elevation_deg=0.0)
    assert 0.5 - flat.eye[1] == pytest.approx(4.6 / (2 * t) + 0.5, rel=1e-12)


@pytest.mark.parametrize(
    "hi, size",
    [((0.2, 0.2, 1.0), (640, 480)), ((0.3, 0.1, 2.0), (480, 640)), ((0.5, 0.5, 0.6), (640, 480))],
)
def test_every_corner_of_a_tall_box_is_in_the_picture_and_the_tallest_near_the_edge(hi, size):
    """Default fov 40° and elevation 20°: the eight corners of a tall box all project inside the image, and
    the largest vertical reach is above half the half-height (the camera is not needlessly far back)."""
    w, h = size
    cam = frame_box((0.0, 0.0, 0.0), hi, w, h)
    eye = torch.tensor(cam.eye, dtype=torch.float64)
    f = torch.tensor(cam.target, dtype=torch.float64) - eye
    f = f / f.norm()
    right = torch.linalg.cross(f, torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64))
    right = right / right.norm()
    up = torch.linalg.cross(right, f)
    tan_v = math.tan(math.radians(20.0))
    tan_h = tan_v * w / h
    corners = torch.cartesian_prod(*[torch.tensor([0.0, b], dtype=torch.float64) for b in hi])  # [8, 3]
    v = corners - eye
    z = v @ f
    assert bool((z > 0).all())
    across, vertical = (v @ right).abs() / z / tan_h, (v @ up).abs() / z / tan_v
    assert float(across.max()) < 1.0 and float(vertical.max()) < 1.0
    assert max(float(across.max()), float(vertical.max())) > 0.5
