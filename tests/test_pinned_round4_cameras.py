"""`capture.fit.read_cameras`, one view at a time, at the edges of what it accepts: an image side is a whole
number of pixels from 1 to `MAX_IMAGE_SIDE` (both ends included; 3.0 is read as 3), a focal length is any
positive finite number, and a rotation is proper within `ROTATION_TOLERANCE` of RᵀR = I. Anything else is a
SceneError naming the file, the view and the key. Unit-level: a cameras.json written to a temporary folder."""

from __future__ import annotations

import json
import math

import pytest

from fracture_gs.capture.fit import MAX_IMAGE_SIDE, read_cameras
from fracture_gs.errors import SceneError

GOOD = {
    "id": 0,
    "img_name": "view0",
    "width": 640,
    "height": 480,
    "position": [1.0, 2.0, 3.0],
    "rotation": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    "fx": 500.0,
    "fy": 400.0,
}


def _read(tmp_path, **changes):
    path = tmp_path / "cameras.json"
    path.write_text(json.dumps([{**GOOD, **changes}]))
    return read_cameras(path)[0]


def _refused(tmp_path, key, value, words):
    with pytest.raises(SceneError) as info:
        _read(tmp_path, **{key: value})
    text = str(info.value)
    assert text.startswith(f"{tmp_path / 'cameras.json'}: camera 0 (view0): {key} "), text
    assert words in text, text


def test_the_limit_is_one_hundred_thousand_pixels():
    """The documented largest image side is 100,000 pixels."""
    assert MAX_IMAGE_SIDE == 100_000


@pytest.mark.parametrize("key", ["width", "height"])
def test_an_image_side_from_one_pixel_to_the_limit_is_accepted_whole(tmp_path, key):
    """1 pixel (the smallest image) and exactly MAX_IMAGE_SIDE are accepted; a whole float (3.0) is read as the
    int 3; the other side keeps its value."""
    for value in (1, 2, MAX_IMAGE_SIDE, 3.0):
        cam = _read(tmp_path, **{key: value})
        assert getattr(cam, key) == int(value) and type(getattr(cam, key)) is int
        other = "height" if key == "width" else "width"
        assert getattr(cam, other) == GOOD[other]


@pytest.mark.parametrize("key", ["width", "height"])
def test_an_image_side_outside_the_range_or_not_whole_is_refused_by_name(tmp_path, key):
    """0, −1, MAX_IMAGE_SIDE + 1, 2.5, true, a string and null are refused with the accepted range in words."""
    for value in (0, -1, MAX_IMAGE_SIDE + 1, 2.5, True, "640", None):
        _refused(tmp_path, key, value, "must be a whole number of pixels from 1 to 100,000")


@pytest.mark.parametrize("key", ["fx", "fy"])
def test_a_focal_length_is_any_positive_finite_number(tmp_path, key):
    """A tiny positive focal length (1e-6 px) is kept as given; 0, a negative one, NaN, infinity and a string are
    refused as not a positive focal length."""
    assert getattr(_read(tmp_path, **{key: 1e-6}), key) == 1e-6
    for value in (0, -5.0, math.nan, math.inf, "500"):
        _refused(tmp_path, key, value, "must be a positive focal length in pixels")


def test_a_rotation_is_proper_within_the_tolerance(tmp_path):
    """A rotation 0.4e-3 off orthonormal (as four written digits leave it) is accepted; 2e-3 off is refused with
    the measured deviation; a reflection (det −1) is refused as one; a 90° turn about z is kept exactly."""
    turn = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    assert _read(tmp_path, rotation=turn).rotation.tolist() == turn
    near = [[1.0002, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]  # RᵀR − I = 4.0e-4
    assert _read(tmp_path, rotation=near).rotation[0, 0] == pytest.approx(1.0002)
    off = [[1.001, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]  # 2.0e-3
    _refused(tmp_path, "rotation", off, "is not a rotation (RᵀR differs from the identity by 0.002")
    mirror = [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    _refused(tmp_path, "rotation", mirror, "is a reflection (determinant −1)")


def test_an_accepted_view_keeps_every_value_it_was_given(tmp_path):
    """Position, focal lengths, image size and name come back as written (float64 tensors, floats, ints)."""
    cam = _read(tmp_path)
    assert cam.position.tolist() == [1.0, 2.0, 3.0]
    assert (cam.fx, cam.fy, cam.width, cam.height, cam.name) == (500.0, 400.0, 640, 480, "view0")
