"""Pinned rules of the automatic capture camera (`capture.camera.frame_box`), round three: where the eye stands
for boxes of unequal depth and height (hand-computed at 0° and 90° elevation), the 15 % margin of a wide box
that is deeper than it is tall, and the defaults it writes into the config (40° field of view, 20° elevation,
+z up).

Unit-level calls: no rendering, no simulation.
"""

from __future__ import annotations

import math

import pytest
import torch

from fracture_gs.capture.camera import frame_box


def test_level_camera_stands_back_from_the_near_face_by_the_framing_distance():
    """At 0° elevation with a 90° field of view on a square image (tan = 1), the eye is on the box centre's
    height, on the −y side, at the framing distance 1.15 × (the larger of the half-width and half-height) in
    front of the box's near face (y = lo_y, i.e. centre − half-depth): box (0,0,0)–(2,4,1) has half-extents
    (1, 2, 0.5), so the eye is 1.15 + 2 = 3.15 m from the centre, at y = 2 − 3.15 = −1.15 m."""
    cam = frame_box((0.0, 0.0, 0.0), (2.0, 4.0, 1.0), 100, 100, fov_deg=90.0, elevation_deg=0.0)
    assert cam.target == pytest.approx((1.0, 2.0, 0.5), abs=1e-12)
    assert cam.eye == pytest.approx((1.0, -1.15, 0.5), abs=1e-12)
    # a tall box (half-height 2 > half-width 0.5): its height sets the distance, 1.15·2 + 0.5 = 2.8 m
    tall = frame_box((0.0, 0.0, 0.0), (1.0, 1.0, 4.0), 100, 100, fov_deg=90.0, elevation_deg=0.0)
    assert tall.eye == pytest.approx((0.5, 0.5 - 2.8, 2.0), abs=1e-12)
    # a wide image (twice as wide as high: tan_h = 2) halves what the width needs: 1.15·1/2 + 2 = 2.575 m
    wide = frame_box((0.0, 0.0, 0.0), (2.0, 4.0, 1.0), 200, 100, fov_deg=90.0, elevation_deg=0.0)
    assert wide.eye == pytest.approx((1.0, 2.0 - 2.575, 0.5), abs=1e-12)


def test_camera_from_straight_above_frames_the_depth_and_stands_above_the_top():
    """At 90° elevation the camera looks straight down: what is 'up' in the picture is the box's y extent, and
    the near face is its top (z = hi_z). Box (0,0,0)–(2,4,1): the distance is 1.15·max(1, 2) + 0.5 = 2.8 m above
    the centre, the eye at (1, 2, 0.5 + 2.8)."""
    cam = frame_box((0.0, 0.0, 0.0), (2.0, 4.0, 1.0), 100, 100, fov_deg=90.0, elevation_deg=90.0)
    assert cam.eye == pytest.approx((1.0, 2.0, 3.3), abs=1e-12)


@pytest.mark.parametrize(
    "lo, hi",
    [((0.0, 0.3, 0.45), (1.0, 0.7, 0.55)), ((0.0, 0.45, 0.3), (1.0, 0.55, 0.7)), ((-1.0, 2.0, 0.0), (1.0, 2.6, 0.1))],
)
def test_nearest_corners_of_a_wide_box_sit_at_the_15_percent_margin(lo, hi):
    """For a box whose width sets the distance, the corners on its face nearest the camera (−y side, top, at the
    default 20° elevation) project exactly at 1/1.15 of the image's half-width, whether the box is deeper (y)
    than tall (z) or the other way round: the distance is measured from the box's supporting plane facing the
    camera, half-depth·cos e + half-height·sin e in front of the centre."""
    cam = frame_box(lo, hi, 640, 480)
    eye = torch.tensor(cam.eye, dtype=torch.float64)
    f = torch.tensor(cam.target, dtype=torch.float64) - eye
    f = f / f.norm()
    right = torch.linalg.cross(f, torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64))
    right = right / right.norm()
    tan_h = math.tan(math.radians(40.0) / 2) * 640 / 480
    corners = torch.cartesian_prod(*[torch.tensor([a, b], dtype=torch.float64) for a, b in zip(lo, hi)])
    v = corners - eye
    u = (v @ right).abs() / (v @ f) / tan_h
    assert float(u.max()) == pytest.approx(1 / 1.15, rel=1e-9)


def test_defaults_are_a_40_degree_view_20_degrees_above_with_z_up():
    """Called without a field of view or elevation, the camera has the config's 40° vertical field of view,
    looks down 20° onto the box centre and keeps +z (the fitted object's up axis) as the picture's up, which
    is also the axis an orbit turns about."""
    lo, hi = (0.1, 0.2, 0.3), (0.9, 0.6, 0.5)
    cam = frame_box(lo, hi, 640, 480)
    assert cam.fov_deg == 40.0
    assert cam.up == (0.0, 0.0, 1.0)
    assert cam == frame_box(lo, hi, 640, 480, fov_deg=40.0, elevation_deg=20.0)
    d = torch.tensor(cam.target, dtype=torch.float64) - torch.tensor(cam.eye, dtype=torch.float64)
    assert math.degrees(math.atan2(-float(d[2]), float(d[1]))) == pytest.approx(20.0)
    assert float(d[0]) == 0.0
    other = frame_box(lo, hi, 640, 480, fov_deg=30.0, elevation_deg=45.0)
    assert other.fov_deg == 30.0 and other.up == (0.0, 0.0, 1.0)
