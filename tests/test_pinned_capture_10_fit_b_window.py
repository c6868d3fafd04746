"""Pinned rules of the automatic region of interest's window (`capture.fit.auto_roi`), round ten:

- the whole scene is voxelled while its grid, counted as the product of the voxels the grid really has along
  each of the three axes (extent / h + 1), holds at most 64,000,000 voxels; one voxel more and only the
  window, half the core's extent around the core on every side, is voxelled. The count is a product of three
  unequal axes here (13 × 401 × 12,277 = 64,000,001 against 16 × 400 × 10,000 = 64,000,000), not a cube;
- the window holds its faces: a Gaussian exactly on a lower or an upper face is voxelled, one 1/64 beyond is
  not;
- a window holding fewer than 10 Gaussians (the per-axis quantiles meet in a box that holds almost nothing)
  is a SceneError naming the file, the percentile and its complement, and the count; 10 is enough.

Scenes are lattices whose quantiles, voxel (h = 1) and window are exact in binary; a spy stands in for the
voxeller (`auto_roi_connected`) where a 64-million-voxel grid would otherwise be built.
"""

from __future__ import annotations

import pytest
import torch
from captureutil import voxeller_spy

from fracture_gs.capture.fit import auto_roi
from fracture_gs.errors import SceneError

F64 = torch.float64


def _lattice(xs, ys, zs) -> torch.Tensor:  # [27, 3]
    g = torch.meshgrid(
        torch.tensor(xs, dtype=F64), torch.tensor(ys, dtype=F64), torch.tensor(zs, dtype=F64), indexing="ij"
    )
    return torch.stack(g, -1).reshape(-1, 3)


@pytest.mark.parametrize(
    "short, y_far, z_far, voxelled",
    [(12.0, 400.0, 12_276.0, 27), (15.0, 399.0, 9_999.0, 29)],
    ids=["13x401x12277 = 64M + 1", "16x400x10000 = 64M"],
)
def test_the_voxel_cap_counts_the_product_of_three_unequal_axes(monkeypatch, short, y_far, z_far, voxelled):
    """A 3 × 3 × 3 lattice x ∈ {0, s/2, s}, y, z ∈ {0, 24, 48} and two floaters, (0, Y, 0) and (0, 0, Z).
    At percentile 5 (positions 1.4 and 26.6 of 28) the core is [0, s] × [0, 48]², so h = 48/48 = 1 and the
    grid is (s + 1) × (Y + 1) × (Z + 1) voxels. s = 12, Y = 400, Z = 12,276 is 64,000,001 voxels, one over the
    cap: only the window [−6, 18] × [−24, 72]² is voxelled, the 27 lattice Gaussians. s = 15, Y = 399,
    Z = 9,999 is 64,000,000 exactly, within the cap: all 29 are voxelled."""
    x = torch.cat(
        [
            _lattice([0.0, short / 2, short], [0.0, 24.0, 48.0], [0.0, 24.0, 48.0]),
            torch.tensor([[0.0, y_far, 0.0], [0.0, 0.0, z_far]], dtype=F64),
        ]
    )
    seen = voxeller_spy(monkeypatch)
    auto_roi(x, 5.0)
    given, core_lo, core_hi, h = seen[0]
    assert (core_lo, core_hi, h) == ([0.0, 0.0, 0.0], [short, 48.0, 48.0], 1.0)
    assert len(given) == voxelled
    if voxelled == 27:
        assert torch.equal(given, x[:27])


def test_the_window_holds_its_faces(monkeypatch):
    """The lattice {0, 24, 48}³, floaters 400 away on each axis (over the cap), one Gaussian on each of the
    window's six faces (−24 or 72 on one axis, 24 on the others) and one 1/64 beyond each face. At percentile
    10 (positions 4.1 and 36.9 of 41) the core is [0, 48]³ and the window [−24, 72]³: the 27 lattice Gaussians
    and the 6 on the faces are voxelled, none beyond a face and no floater."""
    lattice = _lattice([0.0, 24.0, 48.0], [0.0, 24.0, 48.0], [0.0, 24.0, 48.0])
    eye = torch.eye(3, dtype=F64)
    mid = torch.full((3,), 24.0, dtype=F64)
    on = torch.cat([mid - 48 * eye, mid + 48 * eye])  # [6, 3] x = -24, y = -24, z = -24, x = 72, ...
    beyond = torch.cat([mid - (48 + 1 / 64) * eye, mid + (48 + 1 / 64) * eye])
    x = torch.cat([lattice, 400.0 * eye, on, beyond])
    seen = voxeller_spy(monkeypatch)
    auto_roi(x, 10.0)
    given, core_lo, core_hi, h = seen[0]
    assert (core_lo, core_hi, h) == ([0.0] * 3, [48.0] * 3, 1.0)
    assert torch.equal(given, torch.cat([lattice, on]))


def _slabs_and_rod(n_rod: int) -> torch.Tensor:  # [48 + n_rod, 3]
    """Three slabs of 16 Gaussians, each on {0, 16, 32, 48}² across one axis and 10⁵ out along it, and a rod
    of n_rod Gaussians at (20 + k/10)(1, 1, 1). Each axis alone has 2/3 of its Gaussians in [0, 48], so its 30 %
    and 70 % quantiles lie there (about 20.1 and 48), but every slab Gaussian is 10⁵ out on one axis: the
    window around that core holds only the rod."""
    g = torch.tensor([0.0, 16.0, 32.0, 48.0], dtype=F64)
    a, b = (t.reshape(-1) for t in torch.meshgrid(g, g, indexing="ij"))
    far = torch.full_like(a, 1e5)
    slabs = torch.cat([torch.stack([a, b, far], 1), torch.stack([a, far, b], 1), torch.stack([far, a, b], 1)])
    rod = (20.0 + 0.1 * torch.arange(n_rod, dtype=F64))[:, None].expand(n_rod, 3)
    return torch.cat([slabs, rod])


def test_a_window_of_nine_gaussians_is_refused_in_one_sentence():
    """The slabs and a rod of 9: the window holds 9 of the 57 Gaussians, fewer than 10, so the automatic
    region of interest is refused, naming the file, the percentile, its complement (70th), the count, and the
    two ways out."""
    with pytest.raises(SceneError) as info:
        auto_roi(_slabs_and_rod(9), 30.0, "scene.ply: ")
    assert str(info.value) == (
        "scene.ply: capture.percentile = 30 bounds the automatic region of interest by the 30th and 70th "
        "percentiles on every axis, a box that holds 9 of 57 Gaussians; use a smaller percentile, e.g. 1 (the "
        'default), or set capture.roi = "box" with roi_lower and roi_upper.'
    )


def test_a_window_of_ten_gaussians_is_enough():
    """The slabs and a rod of 10: the window holds exactly 10 Gaussians, which is enough; the object is the
    rod, from 20 to 20.9 on every axis, widened by 2 % of that (and 1e-9) each side."""
    lo, hi = auto_roi(_slabs_and_rod(10), 30.0, "scene.ply: ")
    pad = 0.02 * 0.9 + 1e-9
    assert lo.tolist() == pytest.approx([20.0 - pad] * 3, abs=1e-12)
    assert hi.tolist() == pytest.approx([20.9 + pad] * 3, abs=1e-12)
