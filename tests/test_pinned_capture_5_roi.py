"""Pinned rules of the automatic region of interest (`capture.fit.auto_roi` and `auto_roi_connected`), round
five: the object is everything connected to its robust core, and its bounds are widened by 2 % each side.

- the core: per axis, the `percentile` % and (100 − `percentile`) % quantiles of the Gaussians;
- connected: Gaussians on voxels of 1/48 of the core's longest side, each voxel grown by one voxel, touching as
  26-neighbours, so two occupied voxels up to 3 apart on every axis (two empty voxels between) are one object
  and 4 apart are two; a connected part is kept when one of its Gaussians lies in the core box;
- a scene whose voxel grid would exceed 64 million voxels (a floater far away) is voxelled only within half the
  core's extent around the core on every side: what lies beyond is cut off, even if connected.

Hand-built scenes: lattices and rods of points whose voxels and quantiles are known exactly.
"""

from __future__ import annotations

import pytest
import torch

from fracture_gs.capture.fit import auto_roi, auto_roi_connected

F64 = torch.float64


def _rod(start, step, n, axis) -> torch.Tensor:  # [n, 3]
    """n points from `start` in steps of `step` along `axis`, at x = y = z = 5 across it."""
    x = torch.full((n, 3), 5.0, dtype=F64)
    x[:, axis] = start + step * torch.arange(n, dtype=F64)
    return x


def lattice_with_rods() -> torch.Tensor:  # [17796, 3]
    """A 10 m lattice cube [0, 10]³ (26 points a side, 0.4 apart: about two voxels, so one connected body) with
    three rods 0.1 apart: down from its bottom to z = −3.95, up from its top to z = 19.95 and out of its −x
    face to x = −7.95. The rods hold under 1 % of the points, so the 1 % core is the cube, [0, 10]³ exactly."""
    g = torch.arange(0, 10.0001, 0.4, dtype=F64)
    cube = torch.stack(torch.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    return torch.cat([cube, _rod(-0.05, -0.1, 40, 2), _rod(10.05, 0.1, 100, 2), _rod(-0.05, -0.1, 80, 0)])


def widened(lo, hi):
    """The bounds [lo, hi] of the kept Gaussians widened by 2 % of their extent (and 1e-9) each side."""
    lo, hi = torch.tensor(lo, dtype=F64), torch.tensor(hi, dtype=F64)
    pad = 0.02 * (hi - lo) + 1e-9
    return (lo - pad).tolist(), (hi + pad).tolist()


def test_without_far_floaters_everything_connected_to_the_core_is_the_object():
    """The lattice and its three rods, however far the rods reach beyond the core, are one object: the bounds
    are the rods' tips (x −7.95, z −3.95 and 19.95) and the cube's faces, widened by 2 %."""
    lo, hi = auto_roi(lattice_with_rods(), 1.0)
    want = widened([-7.95, 0.0, -3.95], [10.0, 10.0, 19.95])
    assert lo.tolist() == pytest.approx(want[0], abs=1e-9) and hi.tolist() == pytest.approx(want[1], abs=1e-9)


@pytest.mark.parametrize("far", [2700.0, 1e6])
def test_with_a_far_floater_the_object_is_searched_within_half_the_core_around_it(far):
    """A floater at x = 2700 (a voxel grid of about 74 million voxels) or 1e6 m away: only what lies within half
    the core's extent (5 m) around the core [0, 10]³ is voxelled. The floater is dropped; the rod down to
    z = −3.95 lies inside that window and is kept whole; the rods to x = −7.95 and z = 19.95 are cut at the
    window's faces x = −5 and z = 15 (their last points inside: −4.95 and 14.95)."""
    x = torch.cat([lattice_with_rods(), torch.tensor([[far, 5.0, 5.0]], dtype=F64)])
    lo, hi = auto_roi(x, 1.0)
    want = widened([-4.95, 0.0, -3.95], [10.0, 10.0, 14.95])
    assert lo.tolist() == pytest.approx(want[0], abs=1e-9) and hi.tolist() == pytest.approx(want[1], abs=1e-9)


@pytest.mark.parametrize("percentile, reaches_b", [(1.0, True), (10.0, True), (25.0, False)])
def test_the_core_is_the_percentile_and_its_complement(percentile, reaches_b):
    """Two rods along x: A, 800 points from 0 to 0.799, and B, 200 points from 5 to 5.199, far apart. The core
    runs from the `percentile` % to the (100 − `percentile`) % quantile: at 1 % and 10 % its upper end (the
    990th or 900th point) lies in B, so B is part of the object; at 25 % (the 750th point, in A) it is not."""
    a = torch.zeros(800, 3, dtype=F64)
    a[:, 0] = 0.001 * torch.arange(800, dtype=F64)
    b = torch.zeros(200, 3, dtype=F64)
    b[:, 0] = 5.0 + 0.001 * torch.arange(200, dtype=F64)
    lo, hi = auto_roi(torch.cat([a, b]), percentile)
    want = widened([0.0, 0.0, 0.0], [5.199 if reaches_b else 0.799, 0.0, 0.0])
    assert lo.tolist() == pytest.approx(want[0], abs=1e-9) and hi.tolist() == pytest.approx(want[1], abs=1e-9)


def _connected_bounds(points, core=((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))):
    x = torch.tensor(points, dtype=F64)
    lo, hi = auto_roi_connected(x, torch.tensor(core[0], dtype=F64), torch.tensor(core[1], dtype=F64), 1.0)
    return lo.tolist(), hi.tolist()


@pytest.mark.parametrize(
    "other, joined",
    [
        ((3.0, 0.0, 0.0), True),  # voxels 0 and 3: two empty voxels between, bridged by the growth
        ((4.0, 0.0, 0.0), False),  # voxels 0 and 4: three empty voxels between
        ((3.0, 3.0, 3.0), True),  # diagonal: the grown voxels touch at a corner (26-neighbours)
        ((4.0, 3.0, 3.0), False),
    ],
)
def test_two_voxels_are_one_object_up_to_three_apart(other, joined):
    """With voxels of 1 m and the core at the origin's Gaussian: a second Gaussian 3 voxels away, along an axis
    or diagonally, is part of the object; 4 voxels away it is background."""
    lo, hi = _connected_bounds([(0.0, 0.0, 0.0), other])
    far = other if joined else (0.0, 0.0, 0.0)
    want = widened([0.0, 0.0, 0.0], list(far))
    assert lo == pytest.approx(want[0], abs=1e-12) and hi == pytest.approx(want[1], abs=1e-12)


def test_a_chain_is_one_object_and_the_core_picks_which():
    """A chain of Gaussians 3 voxels apart (0, 3, 6) and one 4 voxels beyond (10): the chain is the object when
    the core holds its first Gaussian; with the core on the lone one, it alone is; with no Gaussian in the core
    box (it lies between voxels), nothing is dropped."""
    pts = [(0.0, 0.0, 0.0), (3.0, 0.0, 0.0), (6.0, 0.0, 0.0), (10.0, 0.0, 0.0)]
    lo, hi = _connected_bounds(pts)
    want = widened([0.0, 0.0, 0.0], [6.0, 0.0, 0.0])
    assert lo == pytest.approx(want[0], abs=1e-12) and hi == pytest.approx(want[1], abs=1e-12)
    lo, hi = _connected_bounds(pts, core=((9.5, -1.0, -1.0), (10.5, 1.0, 1.0)))
    assert lo == pytest.approx([10.0 - 1e-9, -1e-9, -1e-9], abs=1e-12)
    assert hi == pytest.approx([10.0 + 1e-9, 1e-9, 1e-9], abs=1e-12)
    lo, hi = _connected_bounds(pts, core=((1.0, -1.0, -1.0), (2.0, 1.0, 1.0)))
    want = widened([0.0, 0.0, 0.0], [10.0, 0.0, 0.0])
    assert lo == pytest.approx(want[0], abs=1e-12) and hi == pytest.approx(want[1], abs=1e-12)
