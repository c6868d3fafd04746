"""Pinned rules of the trainer view `capture.camera = "trainer"` draws from (`capture.fit.check_view`), round ten:

- its image is at most 10:1 either way (width over height from 1/10 to 10, both ends included);
- its field of view fov = 2·atan(pixels / 2f) is from 0.1° to 179°, both ends included, across the width with
  fx and across the height with fy, each checked on its own;
- a refusal is one sentence naming the file, the view (by index and shortened name), the key, the focal length,
  the field of view it gives (3 digits), the side it spans and the allowed range "0.1° to 179°", and the fix.

Focal lengths are made from a chosen field of view, f = pixels / (2·tan(fov / 2)); the message's field of view
is checked against that chosen number, written out by hand.
"""

from __future__ import annotations

import math

import pytest
import torch
from badinput import one_line

from fracture_gs.capture.fit import FOV_RANGE, MAX_ASPECT, TrainerCamera, check_view
from fracture_gs.errors import SceneError

F64 = torch.float64
FIX = 'pick another capture.view, or set capture.camera = "auto" to frame the object instead.'


def focal(pixels: int, fov_deg: float) -> float:
    """The focal length [px] that gives `fov_deg` across `pixels`."""
    return pixels / (2 * math.tan(math.radians(fov_deg) / 2))


def cam(width: int, height: int, fx: float, fy: float, name: str = "front") -> TrainerCamera:
    return TrainerCamera(torch.zeros(3, dtype=F64), torch.eye(3, dtype=F64), fx, fy, width, height, name)


def refusal(c: TrainerCamera, index: int = 2) -> str:
    with pytest.raises(SceneError) as info:
        check_view("views/cameras.json", index, c)
    return one_line(info.value)


def test_the_ranges_are_the_documented_ones():
    """Rule: the drawable field of view is 0.1°–179° and the widest image 10:1 (the values the messages print)."""
    assert FOV_RANGE == (0.1, 179.0) and MAX_ASPECT == 10.0


@pytest.mark.parametrize("fov", [0.1 * (1 + 1e-9), 1.0, 60.0, 179.0 * (1 - 1e-9)])
@pytest.mark.parametrize("key", ["fx", "fy"])
def test_a_field_of_view_inside_the_range_is_drawn(fov, key):
    """Rule: a field of view from 0.1° to 179° (just inside either end) on either axis is accepted."""
    fx = focal(800, fov) if key == "fx" else focal(800, 60.0)
    fy = focal(600, fov) if key == "fy" else focal(600, 60.0)
    check_view("views/cameras.json", 0, cam(800, 600, fx, fy))


@pytest.mark.parametrize("fov", [0.1 * (1 - 1e-6), 0.05, 179.0 * (1 + 1e-6), 179.6])
@pytest.mark.parametrize("key, side, pixels", [("fx", "width", 800), ("fy", "height", 600)])
def test_a_field_of_view_outside_the_range_names_its_key_and_side(fov, key, side, pixels):
    """Rule: a field of view just below 0.1° or just above 179° across the width (fx) or the height (fy) is
    refused, naming that key and side, the pixels it spans and the range; the other axis is fine."""
    fx = focal(800, fov) if key == "fx" else focal(800, 60.0)
    fy = focal(600, fov) if key == "fy" else focal(600, 60.0)
    msg = refusal(cam(800, 600, fx, fy))
    assert msg.startswith(f"views/cameras.json: camera 2 (front): {key} = ")
    assert f"px gives a field of view of {fov:.3g}° across its {pixels}-pixel {side}, outside 0.1° to 179°; " in msg
    assert msg.endswith(FIX)


def test_the_field_of_view_message_in_full():
    """Rule: the whole sentence, hand-computed: fx = 1e6 px across 1000 px gives 2·atan(0.0005) = 0.001 rad =
    0.0573°; fy = 1 px across 1000 px gives 2·atan(500) = 180° − 2·atan(1/500) = 179.77°, shown as 180°."""
    msg = refusal(cam(1000, 1000, 1e6, focal(1000, 60.0)), index=0)
    assert msg == (
        "views/cameras.json: camera 0 (front): fx = 1e+06 px gives a field of view of 0.0573° across its "
        "1000-pixel width, outside 0.1° to 179°; " + FIX
    )
    msg = refusal(cam(1000, 1000, focal(1000, 60.0), 1.0, name=""), index=4)
    assert msg == (
        "views/cameras.json: camera 4: fy = 1 px gives a field of view of 180° across its "
        "1000-pixel height, outside 0.1° to 179°; " + FIX
    )


@pytest.mark.parametrize("width, height", [(1000, 100), (100, 1000), (640, 480), (480, 640), (1, 1)])
def test_an_image_up_to_10_to_1_either_way_is_drawn(width, height):
    """Rule: width over height from 1/10 to 10, both ends included, is a camera image (fields of view 60°)."""
    check_view("views/cameras.json", 0, cam(width, height, focal(width, 60.0), focal(height, 60.0)))


@pytest.mark.parametrize("width, height", [(1001, 100), (100, 1001), (1010, 100), (11, 1)])
def test_an_image_over_10_to_1_either_way_is_refused(width, height):
    """Rule: an image wider or taller than 10:1 is refused before its focal lengths, naming its size."""
    msg = refusal(cam(width, height, focal(width, 60.0), focal(height, 60.0), name="  wide\nshot "))
    assert msg == (
        f"views/cameras.json: camera 2 (wide shot): width and height ({width}×{height}) are not a camera image "
        f"(over 10:1); " + FIX
    )
