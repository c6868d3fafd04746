"""Pinned rules of which way is up in a captured scene and how it is turned onto +z (`capture.fit.detect_up`,
`capture.fit.rotation_onto_z`), round ten:

- `capture.up` other than `auto` names the up axis outright;
- otherwise the trainer's cameras vote: their y axes point down in the image (OpenCV), so up is minus the mean of
  their y axes, normalized; the note names how many cameras voted and the axis closest to the result;
- when that mean is 1e-6 long or shorter (the views cancel: e.g. one upright and one upside down) the cameras
  say nothing, and −y is assumed (COLMAP's convention), as it is without cameras; the bound is inclusive;
- rotation_onto_z(u) is the smallest rotation taking u to +z: it turns about u × z by the angle between u and z
  (trace 1 + 2·cos θ), keeps that axis fixed, and for u = −z is the half turn about x, diag(1, −1, −1).

The threshold cases are built so the mean is exact in float64: four views whose y axes are (2d, s, 0),
(2d, −s, 0), (0, 0, 1), (0, 0, −1) with s = √(1 − 4d²) sum to (4d, 0, 0) without rounding, so the mean is
(d, 0, 0) and its length is d exactly.
"""

from __future__ import annotations

import math

import pytest
import torch

from fracture_gs.capture.fit import TrainerCamera, detect_up, rotation_onto_z
from fracture_gs.config import CaptureConfig

F64 = torch.float64
ASSUMED = "up axis -y assumed (COLMAP's convention; set capture.up)"


def camera(y_axis) -> TrainerCamera:
    """A view whose camera y axis (image down) is the unit vector `y_axis`; x and z complete a proper frame."""
    y = torch.tensor(y_axis, dtype=F64)
    helper = torch.tensor([1.0, 0.0, 0.0], dtype=F64) if abs(float(y[0])) < 0.9 else torch.tensor([0.0, 1.0, 0.0])
    x = torch.linalg.cross(y, helper.to(F64))
    x = x / x.norm()
    z = torch.linalg.cross(x, y)
    R = torch.stack([x, y, z], dim=1)  # columns: the camera's axes in the world
    assert torch.equal(R[:, 1], y) and float(torch.linalg.det(R)) == pytest.approx(1.0)
    return TrainerCamera(torch.zeros(3, dtype=F64), R, 500.0, 500.0, 640, 480, "v")


def cancelling_views(d: float) -> list[TrainerCamera]:
    """Four views whose y axes average to exactly (d, 0, 0)."""
    s = math.sqrt(1.0 - 4.0 * d * d)
    views = [camera((2 * d, s, 0.0)), camera((2 * d, -s, 0.0)), camera((0.0, 0.0, 1.0)), camera((0.0, 0.0, -1.0))]
    mean = torch.stack([c.rotation[:, 1] for c in views]).mean(0)
    assert mean.tolist() == [d, 0.0, 0.0] and float(mean.norm()) == d
    return views


@pytest.mark.parametrize("name, axis", [("+x", (1, 0, 0)), ("-z", (0, 0, -1)), ("+y", (0, 1, 0))])
def test_the_configured_up_axis_wins_over_the_cameras(name, axis):
    """Rule: capture.up names the axis outright, whatever the cameras say (here they say +z)."""
    up, note = detect_up(CaptureConfig(up=name), [camera((0.0, 0.0, -1.0))] * 3)
    assert up.tolist() == [float(a) for a in axis]
    assert note == f"up axis {name} (capture.up)"


def test_up_is_minus_the_mean_camera_y_axis_normalized():
    """Rule: with capture.up = "auto", up = −mean(y axes) / |mean|; hand-computed: y axes (0.6, 0, −0.8) and
    (0, 0, −1) average to (0.3, 0, −0.9), so up = (−0.3, 0, 0.9) / √0.9 = (−0.31623, 0, 0.94868), nearest +z."""
    up, note = detect_up(CaptureConfig(), [camera((0.6, 0.0, -0.8)), camera((0.0, 0.0, -1.0))])
    torch.testing.assert_close(up, torch.tensor([-0.3, 0.0, 0.9], dtype=F64) / math.sqrt(0.9))
    assert float(up.norm()) == pytest.approx(1.0, abs=1e-15)
    assert note == "up axis from the 2 trainer cameras (closest to +z)"


def test_views_that_cancel_exactly_say_nothing():
    """Rule: an upright and an upside-down view (y axes (0, 1, 0) and (0, −1, 0)) average to zero: −y is
    assumed, a finite unit vector, not the 0/0 of normalizing a zero mean."""
    up, note = detect_up(CaptureConfig(), [camera((0.0, 1.0, 0.0)), camera((0.0, -1.0, 0.0))])
    assert up.tolist() == [0.0, -1.0, 0.0]
    assert note == ASSUMED


def test_without_cameras_minus_y_is_assumed():
    """Rule: no cameras.json: −y is assumed and the note says how to set it."""
    up, note = detect_up(CaptureConfig(), [])
    assert up.tolist() == [0.0, -1.0, 0.0] and note == ASSUMED


@pytest.mark.parametrize("d", [1e-6, 5e-7, 1e-9])
def test_a_mean_of_at_most_1e6_is_too_short_to_vote(d):
    """Rule: a mean y axis of length 1e-6, the bound included, or shorter, gives no up axis: −y is assumed."""
    up, note = detect_up(CaptureConfig(), cancelling_views(d))
    assert up.tolist() == [0.0, -1.0, 0.0]
    assert note == ASSUMED


@pytest.mark.parametrize("d", [math.nextafter(1e-6, 1.0), 2e-6, 1e-3])
def test_a_mean_just_over_1e6_votes(d):
    """Rule: a mean y axis longer than 1e-6, by as little as one ulp, is used: the mean (d, 0, 0) gives up = −x,
    the note counts the 4 views."""
    up, note = detect_up(CaptureConfig(), cancelling_views(d))
    torch.testing.assert_close(up, torch.tensor([-1.0, 0.0, 0.0], dtype=F64), rtol=0, atol=1e-12)
    assert note == "up axis from the 4 trainer cameras (closest to -x)"


@pytest.mark.parametrize("u", [(1.0, 2.0, 3.0), (-0.3, 0.1, -2.0), (0.0, -1.0, 0.0), (5.0, 0.0, 0.01)])
def test_rotation_onto_z_turns_about_u_cross_z_by_their_angle(u):
    """Rule: the rotation is the smallest one: it keeps the axis u × z fixed and its angle (from the trace,
    1 + 2·cos θ) is the angle between u and z, so a vector in the (u, z) plane stays in it."""
    v = torch.tensor(u, dtype=F64)
    R = rotation_onto_z(v)
    z = torch.tensor([0.0, 0.0, 1.0], dtype=F64)
    n = v / v.norm()
    torch.testing.assert_close(R @ n, z)
    axis = torch.linalg.cross(n, z)
    torch.testing.assert_close(R @ axis, axis)
    cos_theta = float(n[2])
    assert float(torch.trace(R)) == pytest.approx(1 + 2 * cos_theta, abs=1e-12)
    assert float(torch.linalg.det(R)) == pytest.approx(1.0, abs=1e-12)
    # z itself turns by θ about the same axis: it stays perpendicular to the axis, at angle θ from where it was
    w = R @ z
    assert float(w @ axis) == pytest.approx(0.0, abs=1e-12)
    assert float(w @ z) == pytest.approx(cos_theta, abs=1e-12)


def test_rotation_onto_z_of_z_and_of_minus_z():
    """Rule: +z (any length) needs no turn, the identity; −z is turned by the half turn about x, diag(1, −1, −1)."""
    assert torch.equal(rotation_onto_z(torch.tensor([0.0, 0.0, 2.0], dtype=F64)), torch.eye(3, dtype=F64))
    R = rotation_onto_z(torch.tensor([0.0, 0.0, -0.5], dtype=F64))
    assert R.tolist() == [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]


def test_rotation_onto_z_of_a_horizontal_axis_is_a_quarter_turn():
    """Rule: hand-computed: +x goes to +z by a quarter turn about x × z = −y, which takes z to −x and keeps y."""
    R = rotation_onto_z(torch.tensor([1.0, 0.0, 0.0], dtype=F64))
    expected = torch.tensor([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]], dtype=F64)
    torch.testing.assert_close(R, expected, rtol=0, atol=1e-15)
    R = rotation_onto_z(torch.tensor([0.0, -3.0, 0.0], dtype=F64))  # −y, COLMAP's up: about −y × z = −x
    expected = torch.tensor([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]], dtype=F64)
    torch.testing.assert_close(R, expected, rtol=0, atol=1e-15)
