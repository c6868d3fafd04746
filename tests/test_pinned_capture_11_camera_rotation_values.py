"""Pinned rule of a cameras.json view's rotation values (`capture.fit.read_cameras`), round eleven: the first entry
that is not a finite number (NaN, ±Infinity, a string, a boolean, null) is named in the message, whichever row
and column it sits in, and a rotation of finite numbers passes this check (it then meets the rotation and
reflection checks, pinned in tests/test_pinned_capture_8_camera_rotation.py).
"""

from __future__ import annotations

import json

import pytest
from badinput import one_line

from fracture_gs.capture.fit import read_cameras
from fracture_gs.errors import SceneError

IDENTITY = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
FIX = 'fix that entry, point capture.cameras_json at the trainer\'s file, or set capture.up and capture.camera = "auto"'


def write(tmp_path, rotation_text: str):
    view = {"img_name": "v0", "position": [1.0, 2.0, 3.0], "rotation": "ROT", "fx": 500.0, "fy": 500.0}
    text = json.dumps([{**view, "width": 640, "height": 480}]).replace('"ROT"', rotation_text)
    path = tmp_path / "cameras.json"
    path.write_text(text)
    return path


@pytest.mark.parametrize("row, col", [(0, 0), (1, 2), (2, 1)])
@pytest.mark.parametrize(
    "value, named",
    [("NaN", "the non-finite number nan"), ("-Infinity", "the non-finite number -inf"), ('"1"', "the string '1'")],
)
def test_the_first_value_that_is_not_a_finite_number_is_named(tmp_path, row, col, value, named):
    """A rotation whose entry (row, col) is NaN, −∞ or a string is refused, naming that value, in one sentence
    that names the file, the view and the way out."""
    rows = [[json.dumps(v) for v in r] for r in IDENTITY]
    rows[row][col] = value
    path = write(tmp_path, "[" + ", ".join("[" + ", ".join(r) + "]" for r in rows) + "]")
    with pytest.raises(SceneError) as info:
        read_cameras(path)
    assert one_line(info.value) == (
        f"{path}: camera 0 (v0): rotation holds {named}; it must be a 3×3 array of finite numbers; {FIX} so the "
        "file is not needed."
    )


def test_two_bad_values_name_the_first_in_row_order(tmp_path):
    """With a string at (0, 2) and NaN at (1, 0), the message names the string: entries are read row by row."""
    path = write(tmp_path, '[[1.0, 0.0, "x"], [NaN, 1.0, 0.0], [0.0, 0.0, 1.0]]')
    with pytest.raises(SceneError, match=r"rotation holds the string 'x'; "):
        read_cameras(path)


def test_a_rotation_of_finite_numbers_is_read(tmp_path):
    """The identity, written with integers and floats alike, passes and is read as the float64 identity."""
    cams = read_cameras(write(tmp_path, "[[1, 0, 0], [0, 1.0, 0], [0, 0, 1]]"))
    assert cams[0].rotation.tolist() == IDENTITY
