"""capture.up beside capture.rotation (issue 34, mutation round 12): the up axis is refused as doing nothing when
the rotation takes another scene axis to +z, judged by the ANGLE between capture.up and the rotation's third row
(cos >= UP_AGREEMENT, about 2.6 degrees), whatever small scale error the validator lets through in the matrix
(|RᵀR − I| <= 1e-3). Every axis, both sides of the bound, the message."""

from __future__ import annotations

import math

import pytest
from badinput import capture_doc, one_line

from fracture_gs.errors import ConfigError
from fracture_gs.io.config import config_from_dict
from fracture_gs.io.config.combinations import UP_AGREEMENT, UP_AXES


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def rotation_to_z(axis, tilt_deg: float = 0.0, scale: float = 1.0) -> list[list[float]]:
    """A proper rotation (times `scale`) whose third row is `axis` tilted by `tilt_deg` towards a perpendicular
    axis: it takes that tilted scene axis to +z."""
    a = axis
    p = (0.0, 0.0, 1.0) if abs(a[2]) < 0.5 else (1.0, 0.0, 0.0)  # a unit axis at right angles to a
    c, s = math.cos(math.radians(tilt_deg)), math.sin(math.radians(tilt_deg))
    r2 = tuple(c * x + s * y for x, y in zip(a, p))
    r0 = tuple(c * y - s * x for x, y in zip(a, p))
    r1 = _cross(r2, r0)  # r0 · (r1 × r2) = +1: a proper rotation
    return [[scale * v for v in row] for row in (r0, r1, r2)]


def loads(up: str, rotation) -> bool:
    try:
        config_from_dict(capture_doc(up=up, rotation=rotation), "probe.toml")
    except ConfigError as err:
        msg = one_line(err)
        assert "capture.up" in msg and "no effect" in msg, msg
        return False
    return True


def test_the_bound_is_about_two_and_a_half_degrees():
    """The documented bound: cos 2.5° passes it, cos 2.65° does not (the tests below sit on both sides)."""
    assert math.cos(math.radians(2.5)) >= UP_AGREEMENT > math.cos(math.radians(2.65))


@pytest.mark.parametrize("up", list(UP_AXES))
def test_each_up_axis_loads_with_a_rotation_that_takes_it_to_z(up):
    """Rule: a rotation taking the capture.up axis to +z agrees with it (exactly or within 2.5°); the same rotation
    with any other capture.up (the opposite axis included) is refused as doing nothing."""
    R = rotation_to_z(UP_AXES[up])
    assert loads(up, R) and loads(up, rotation_to_z(UP_AXES[up], 2.5))
    for other in UP_AXES:
        if other != up:
            assert not loads(other, R), (up, other)
    assert not loads(up, rotation_to_z(UP_AXES[up], 2.65))


@pytest.mark.parametrize("up", ["+z", "-y", "+x"])
def test_the_angle_is_judged_apart_from_the_matrix_scale(up):
    """Rule: the test is the angle (dot product over the row's length), so a rotation scaled by 0.9996 or 1.0004
    (inside the validator's orthonormality tolerance) is judged like the exact one: 2.5° off still loads when the
    row is short, 2.65° off is still refused when the row is long."""
    axis = UP_AXES[up]
    assert loads(up, rotation_to_z(axis, 2.5, 0.9996))
    assert not loads(up, rotation_to_z(axis, 2.65, 1.0004))
    assert loads(up, rotation_to_z(axis, 0.0, 0.9996)) and loads(up, rotation_to_z(axis, 0.0, 1.0004))


def test_the_message_names_the_axis_the_rotation_takes_up():
    """Rule: the refusal shows the scene axis the rotation takes to +z (rounded to 4 digits) and the up axis it
    contradicts, and gives both fixes."""
    with pytest.raises(ConfigError) as info:
        config_from_dict(capture_doc(up="-y", rotation=[[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]), "probe.toml")
    msg = one_line(info.value)
    assert "capture.up = '-y' has no effect" in msg
    assert "takes the scene axis [0.0, 0.0, 1.0] to +z (up), not -y" in msg
    assert "remove capture.up" in msg and "or remove capture.rotation" in msg


def test_auto_up_or_no_rotation_is_never_refused():
    """Rule: with capture.up = "auto" the rotation alone decides, and without a rotation the up axis is used, so
    neither is a contradiction."""
    assert loads("auto", rotation_to_z(UP_AXES["+x"], 40.0))
    for up in UP_AXES:
        assert config_from_dict(capture_doc(up=up), "probe.toml").capture.up == up
