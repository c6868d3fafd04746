"""Pinned rule of the automatic region of interest over far floaters (`capture.fit.auto_roi`), round seventeen:
when the whole scene would take more than 64 million voxels, only the Gaussians within half the core's extent of
the core box, on every side and every axis, are voxelled (the window [lo − ½(hi − lo), hi + ½(hi − lo)]).

The core sits away from the origin ([10, 11]³, an 11³ lattice whose 1 % and 99 % quantiles are exactly 10 and
11), so a window measured from the origin or by hi + lo instead of hi − lo shows. The window is [9.5, 11.5] on
each axis; probes stand 0.05 inside and 0.05 outside each of its six faces, and a floater at 1000 (and −1000)
puts the scene far over the voxel cap. The voxeller is replaced by a recorder (tests/captureutil.py).
"""

from __future__ import annotations

import pytest
import torch
from captureutil import voxeller_spy

from fracture_gs.capture.fit import auto_roi
from fracture_gs.errors import SceneError

F64 = torch.float64


def probes(offset: float) -> torch.Tensor:  # [6, 3]: one point beyond (offset > 0) or inside each window face
    rows = []
    for axis in range(3):
        for face, sign in ((9.5, -1.0), (11.5, 1.0)):
            p = [10.5, 10.5, 10.5]
            p[axis] = face + sign * offset
            rows.append(p)
    return torch.tensor(rows, dtype=F64)


def scene(shift: float = 0.0) -> torch.Tensor:  # [1331 + 12 + 2, 3]
    g = torch.linspace(10.0, 11.0, 11, dtype=F64)
    core = torch.cartesian_prod(g, g, g)
    far = torch.tensor([[1000.0, 1000.0, 1000.0], [-1000.0, -1000.0, -1000.0]], dtype=F64)
    return torch.cat([core, probes(-0.05), probes(0.05), far]) + shift


def test_only_the_gaussians_within_half_the_core_of_the_core_box_are_voxelled(monkeypatch):
    """The voxeller gets the 1331 core points and the 6 probes 0.05 inside the window's faces; the 6 probes
    0.05 outside (below 9.5 and above 11.5 on each axis) and the two floaters at ±1000 are left out; the core it
    is given is [10, 11]³."""
    seen = voxeller_spy(monkeypatch)
    auto_roi(scene(), 1.0)
    ((x, core_lo, core_hi, h),) = seen
    assert core_lo == pytest.approx([10.0] * 3) and core_hi == pytest.approx([11.0] * 3)
    assert h == pytest.approx(1 / 48)
    assert len(x) == 1331 + 6
    kept = {tuple(round(v, 6) for v in p) for p in x.tolist()}
    assert all(tuple(round(v, 6) for v in p) in kept for p in probes(-0.05).tolist())
    assert not any(tuple(round(v, 6) for v in p) in kept for p in probes(0.05).tolist())


def test_the_window_moves_with_the_core_on_the_negative_side(monkeypatch):
    """The same scene shifted by −30 (core [−20, −19]³, window [−20.5, −18.5]): the same 1337 Gaussians are
    voxelled; the window depends on the core's size, not on where it lies."""
    seen = voxeller_spy(monkeypatch)
    auto_roi(scene(-30.0), 1.0)
    ((x, core_lo, core_hi, _),) = seen
    assert core_lo == pytest.approx([-20.0] * 3) and core_hi == pytest.approx([-19.0] * 3)
    assert len(x) == 1337
    assert float(x.min()) == pytest.approx(-20.45) and float(x.max()) == pytest.approx(-18.55)


def test_a_window_with_fewer_than_ten_gaussians_names_the_percentile_and_the_count():
    """Ten points on the diagonal (0, 0, 0) … (9, 9, 9) and floaters at ±1000, percentile 45: the 45th and 55th
    percentiles of 12 values are 3.95 and 5.05, so the core is [3.95, 5.05]³ and the window [3.4, 5.6]³ holds
    the points 4 and 5 only; fewer than 10 is a SceneError naming capture.percentile and "2 of 12"."""
    line = torch.arange(10, dtype=F64)[:, None].repeat(1, 3)
    x = torch.cat([line, torch.tensor([[1000.0] * 3, [-1000.0] * 3], dtype=F64)])
    with pytest.raises(SceneError, match=r"^f\.ply: capture\.percentile = 45 bounds .* holds 2 of 12 Gaussians"):
        auto_roi(x, 45.0, "f.ply: ")
