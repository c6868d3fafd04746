"""Pinned rules of the region of interest (`capture.fit.roi_mask` and `auto_roi`), round eight:

- a sphere ROI needs both its centre and its radius, a box both its corners: either one missing is a SceneError
  naming the file and both keys (not a TypeError from the arithmetic on None); the sphere and the box hold
  their boundary (distance = radius, a coordinate = a corner);
- the automatic ROI voxels the whole scene only while its voxel grid holds at most 64 million voxels, counted as
  the voxels the grid really has along each axis (extent / h + 1, both end voxels): an extent of exactly 400
  voxels a side is 401³ = 64 481 201 voxels and is voxelled within half the core around the core only; 399 a
  side (400³ = 64 000 000) is voxelled whole.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture import fit
from fracture_gs.capture.fit import auto_roi, roi_mask
from fracture_gs.config import CaptureConfig
from fracture_gs.errors import SceneError

F64 = torch.float64
SPHERE_NEEDS = 'scene.ply: capture.roi = "sphere" needs capture.roi_center and capture.roi_radius.'
BOX_NEEDS = 'scene.ply: capture.roi = "box" needs capture.roi_lower and capture.roi_upper.'


@pytest.mark.parametrize(
    "keys",
    [{"roi_center": (0.0, 0.0, 0.0)}, {"roi_radius": 1.0}, {}],
    ids=["centre only", "radius only", "neither"],
)
def test_a_sphere_roi_missing_its_centre_or_its_radius_names_both(keys):
    """capture.roi = "sphere" with only a centre, only a radius or neither is refused in one sentence naming
    the file and both keys."""
    with pytest.raises(SceneError) as info:
        roi_mask(torch.zeros(4, 3), CaptureConfig(roi="sphere", **keys), "scene.ply")
    assert str(info.value) == SPHERE_NEEDS


@pytest.mark.parametrize(
    "keys",
    [{"roi_lower": (0.0, 0.0, 0.0)}, {"roi_upper": (1.0, 1.0, 1.0)}, {}],
    ids=["lower only", "upper only", "neither"],
)
def test_a_box_roi_missing_a_corner_names_both(keys):
    """capture.roi = "box" with one corner or none is refused in one sentence naming the file and both keys."""
    with pytest.raises(SceneError) as info:
        roi_mask(torch.zeros(4, 3), CaptureConfig(roi="box", **keys), "scene.ply")
    assert str(info.value) == BOX_NEEDS


def test_the_sphere_and_the_box_hold_their_boundary():
    """A sphere of radius 2 about (1, 1, 1) holds the points at distance exactly 2 (along each axis, either
    way) and not those at 2 + 1/64; the box [0, 1]³ holds its corners and faces and not 1/64 beyond them; the
    description states the sphere's radius and centre."""
    c = torch.tensor([1.0, 1.0, 1.0], dtype=F64)
    eye = torch.eye(3, dtype=F64)
    on = torch.cat([c + 2 * eye, c - 2 * eye])  # [6, 3] distance 2
    off = torch.cat([c + (2 + 1 / 64) * eye, c - (2 + 1 / 64) * eye])
    inside, text = roi_mask(
        torch.cat([on, off, c[None]]), CaptureConfig(roi="sphere", roi_center=(1.0, 1.0, 1.0), roi_radius=2.0), "s"
    )
    assert inside.tolist() == [True] * 6 + [False] * 6 + [True]
    assert text == "region of interest: sphere r = 2 at (1.0, 1.0, 1.0)"
    corners = torch.tensor([[0, 0, 0], [1, 1, 1], [0, 1, 0.5], [1, 0, 1]], dtype=F64)
    beyond = torch.tensor([[-1 / 64, 0.5, 0.5], [0.5, 1 + 1 / 64, 0.5], [0.5, 0.5, -1 / 64]], dtype=F64)
    box = CaptureConfig(roi="box", roi_lower=(0.0, 0.0, 0.0), roi_upper=(1.0, 1.0, 1.0))
    inside, text = roi_mask(torch.cat([corners, beyond]), box, "s")
    assert inside.tolist() == [True] * 4 + [False] * 3
    assert text == "region of interest: box (capture.roi_lower/upper)"


def cube_and_floaters(d: float) -> torch.Tensor:  # [30, 3]
    """27 Gaussians on the 3 × 3 × 3 lattice {0, 24, 48}³ and one floater d away along each axis. Per axis the
    30 coordinates are 11 zeros, 9 × 24, 9 × 48 and one d: the 5 % and 95 % quantiles (positions 1.45 and 27.55
    of 29) are exactly 0 and 48, so the core is [0, 48]³, its voxel h = 48 / 48 = 1 and the scene's extent d
    voxels a side."""
    g = torch.tensor([0.0, 24.0, 48.0], dtype=F64)
    cube = torch.stack(torch.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    return torch.cat([cube, d * torch.eye(3, dtype=F64)])


@pytest.mark.parametrize("d, voxelled", [(400.0, 27), (399.0, 30), (10_000.0, 27), (100.0, 30)])
def test_the_whole_scene_is_voxelled_up_to_64_million_voxels(monkeypatch, d, voxelled):
    """A scene d voxels across on every axis has (d + 1)³ voxels: 401³ (over 64 M, or far more at d = 10⁴) is
    voxelled only within [core − 24, core + 24] = [−24, 72]³, which leaves the 27 lattice Gaussians; 400³
    = 64 M exactly (or 101³) is voxelled whole, all 30. The core passed on is [0, 48]³ and the voxel 1."""
    seen = []

    def connected(x, core_lo, core_hi, h):
        seen.append((len(x), core_lo.tolist(), core_hi.tolist(), h))
        return core_lo, core_hi  # not voxelled here: a 400³ grid would cost a second and 300 MB

    monkeypatch.setattr(fit, "auto_roi_connected", connected)
    auto_roi(cube_and_floaters(d), 5.0)
    assert seen == [(voxelled, [0.0] * 3, [48.0] * 3, 1.0)]


def test_the_object_of_a_scene_over_the_cap_is_found_in_the_window():
    """With the floaters 400 voxels away (over the cap), the bounds are the lattice's [0, 48]³ widened by 2 %
    of its extent (0.96) and 1e-9: the floaters are neither voxelled nor part of the object."""
    lo, hi = auto_roi(cube_and_floaters(400.0), 5.0)
    pad = 0.02 * 48 + 1e-9
    assert lo.tolist() == [-pad] * 3 and hi.tolist() == [48 + pad] * 3
