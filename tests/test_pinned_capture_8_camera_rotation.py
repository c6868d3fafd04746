"""Pinned rule of a cameras.json view's rotation (`capture.fit.read_cameras`), round eight: the rotation must be
orthonormal within ROTATION_TOLERANCE, the largest |RᵀR − I| entry, tolerance included (the trainer writes
rotations to a few digits), and proper (determinant +1).

R = [[1, e, 0], [0, 1, 0], [0, 0, 1]] has RᵀR − I = [[0, e, 0], [e, e², 0], [0, 0, 0]]: its largest entry is e
itself, exactly (the products with 0 and 1 are exact), so e = ROTATION_TOLERANCE sits on the bound.
"""

from __future__ import annotations

import json
import math

import pytest
import torch

from fracture_gs.capture.fit import read_cameras
from fracture_gs.errors import SceneError
from fracture_gs.io.config.validate import ROTATION_TOLERANCE


def view(rotation) -> dict:
    return {
        "img_name": "v0",
        "position": [1.0, 2.0, 3.0],
        "rotation": rotation,
        "fx": 500.0,
        "fy": 500.0,
        "width": 640,
        "height": 480,
    }


def sheared(e: float) -> list:
    return [[1.0, e, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]


def write(tmp_path, rotation):
    path = tmp_path / "cameras.json"
    path.write_text(json.dumps([view(rotation)]))
    return path


@pytest.mark.parametrize("e", [ROTATION_TOLERANCE, -ROTATION_TOLERANCE, 0.5 * ROTATION_TOLERANCE, 0.0])
def test_a_rotation_off_by_up_to_the_tolerance_is_read_as_written(tmp_path, e):
    """|RᵀR − I| up to ROTATION_TOLERANCE (1e-3), the bound included, either sign: the view is read, its
    rotation kept as written (the fit uses only its axes)."""
    assert ROTATION_TOLERANCE == 1e-3
    (cam,) = read_cameras(write(tmp_path, sheared(e)))
    assert cam.rotation.tolist() == sheared(e)
    assert (cam.fx, cam.fy, cam.width, cam.height, cam.name) == (500.0, 500.0, 640, 480, "v0")


@pytest.mark.parametrize("e", [math.nextafter(ROTATION_TOLERANCE, 1.0), -2 * ROTATION_TOLERANCE, 0.1])
def test_a_rotation_off_by_more_than_the_tolerance_is_refused_with_its_error(tmp_path, e):
    """One ulp over the tolerance is refused, in one sentence naming the file, the view and the key, with the
    error |RᵀR − I| to 3 digits."""
    path = write(tmp_path, sheared(e))
    with pytest.raises(SceneError) as info:
        read_cameras(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}: camera 0 (v0): rotation is not a rotation (RᵀR differs from the identity by ")
    assert f"by {abs(e):.3g});" in msg


def test_a_reflection_is_refused_even_when_orthonormal(tmp_path):
    """diag(1, 1, −1) is orthonormal (RᵀR = I) but a reflection: refused as one."""
    path = write(tmp_path, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]])
    with pytest.raises(SceneError, match=r"rotation is a reflection \(determinant −1\)"):
        read_cameras(path)
    assert read_cameras(write(tmp_path, [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]))[0].rotation.equal(
        torch.tensor([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]], dtype=torch.float64)
    )
