"""Per-fragment boxes on a grid whose origin is not zero (`boxes.kernels.fragment_bounds` through
`FragmentBoxes.fit`).

Box k is the range of fragment k's stencil nodes, base = ⌊(x − origin)/Δx − ½⌋ in float64, widened by the slack and
clamped into the grid. Every other box test puts the grid's origin at 0, where x − origin and x + origin are the same
number; here the origin is off zero on every axis (a different amount on each), the grid is not a cube, the fragments
are interleaved so a thread's run of 32 particles changes fragment many times and returns to earlier ones, the last
thread is partial, and unassigned particles (fragment −1) belong to box 0. The expected boxes are computed here in
torch from the rule, not from the kernel.
"""

import torch

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.boxes.fragment_boxes import BOUNDS_RUN, FragmentBoxes

SHAPE = (26, 21, 23)  # nodes per axis, a different count on each
ORIGIN = (-0.37, 0.23, 0.11)  # a different offset on each axis
DX = 0.05
N = 1001  # not a multiple of BOUNDS_RUN: the last thread holds a partial run


def _scene():
    """Three fragments in overlapping blobs inside the grid (x ∈ origin + [0.15, 0.85]·extent), shuffled so that
    consecutive particles mostly differ in fragment, plus a few unassigned particles (−1) far from fragment 0's blob
    that must widen box 0."""
    g = torch.Generator().manual_seed(14)
    extent = torch.tensor(SHAPE, dtype=torch.float64) * DX
    origin = torch.tensor(ORIGIN, dtype=torch.float64)
    centres = torch.tensor([[0.35, 0.4, 0.45], [0.6, 0.5, 0.4], [0.5, 0.65, 0.6]], dtype=torch.float64)
    sizes = torch.tensor([[0.15, 0.2, 0.1], [0.2, 0.1, 0.2], [0.1, 0.15, 0.2]], dtype=torch.float64)
    fragment = torch.randint(0, 3, (N,), generator=g, dtype=torch.int32)
    u = torch.rand(N, 3, generator=g, dtype=torch.float64) * 2 - 1
    frac = centres[fragment.long()] + sizes[fragment.long()] * u
    fragment[::97] = -1  # unassigned: box 0's particles
    frac[::97] = torch.tensor([0.8, 0.2, 0.82], dtype=torch.float64)  # far from fragment 0's blob on every axis
    x = (origin + frac * extent).float()  # [N, 3]
    return x, fragment


def _expected(x, fragment, slack, K):
    """Box lo and hi (inclusive) of each fragment from the rule, in float64 like the kernel."""
    origin = torch.tensor(ORIGIN, dtype=torch.float64)
    base = torch.floor((x.double() - origin) / DX - 0.5).long()  # [N, 3]
    top = torch.tensor(SHAPE) - 1
    owner = fragment.long().clamp_min(0)
    los, his = [], []
    for k in range(K):
        mine = owner == k
        lo = (base[mine].amin(0) - slack).clamp_min(0).minimum(top)
        hi = torch.maximum((base[mine].amax(0) + 2 + slack).minimum(top), lo)
        los.append(lo)
        his.append(hi)
    return torch.stack(los), torch.stack(his)


def test_boxes_follow_the_stencils_measured_from_an_off_zero_origin():
    """On a grid at origin (−0.37, 0.23, 0.11), Δx = 0.05, of 26 × 21 × 23 nodes, each fragment's box is exactly
    [min base − slack, max base + 2 + slack] per axis with base = ⌊(x − origin)/Δx − ½⌋, clamped into the grid,
    for slack 0, 1 and 3 (the buffer offsets are the running sums of the box volumes); the unassigned particles
    widen box 0. Fragments change within nearly every run of 32 particles a thread reduces, and the last thread's run
    is partial, so a bound lost when a run changes fragment or ends shows here."""
    ensure_warp()
    x, fragment = _scene()
    assert N % BOUNDS_RUN != 0
    owner = fragment.long().clamp_min(0)
    changes = int((owner[1:] != owner[:-1]).sum())
    assert changes > N // 2, "consecutive particles mostly change fragment"
    boxes = FragmentBoxes(SHAPE, ORIGIN, DX, "cpu", max_fragments=4)
    for slack in (0, 1, 3):
        boxes.fit(x, fragment, slack=slack)
        assert boxes.K == 3
        lo, hi = _expected(x, fragment, slack, 3)
        assert boxes.lo[:3].long().tolist() == lo.tolist(), f"slack {slack}"
        assert (boxes.lo[:3].long() + boxes.dims[:3].long() - 1).tolist() == hi.tolist(), f"slack {slack}"
        volumes = (hi - lo + 1).prod(1)
        assert boxes.offset[:4].long().tolist() == [0, *torch.cumsum(volumes, 0).tolist()]
    assigned = fragment >= 0
    lo0, hi0 = _expected(x[assigned], fragment[assigned], 0, 1)  # box 0 without the unassigned particles
    boxes.fit(x, fragment, slack=0)
    wider = (boxes.lo[0].long() < lo0[0]).any() or (boxes.lo[0].long() + boxes.dims[0].long() - 1 > hi0[0]).any()
    assert bool(wider), "the unassigned particles widen box 0"


def test_a_box_at_the_grids_far_corner_is_clamped_into_the_grid():
    """Particles within a cell of the grid's last nodes (measured from the off-zero origin) have stencils reaching
    past the grid; their box ends at the grid's last node on every axis and starts at its lowest base minus the
    slack, while a fragment near the first nodes gets a box clamped at node 0: the bounds are measured from the
    origin, not from 0."""
    ensure_warp()
    origin = torch.tensor(ORIGIN, dtype=torch.float64)
    top = torch.tensor(SHAPE, dtype=torch.float64) - 1
    g = torch.Generator().manual_seed(3)
    far = origin + (top - 1.2 + 0.6 * torch.rand(40, 3, generator=g, dtype=torch.float64)) * DX  # ξ near the top
    near = origin + (0.9 + 0.6 * torch.rand(40, 3, generator=g, dtype=torch.float64)) * DX  # ξ ∈ [0.9, 1.5]
    x = torch.cat([far, near]).float()
    fragment = torch.cat([torch.zeros(40, dtype=torch.int32), torch.ones(40, dtype=torch.int32)])
    boxes = FragmentBoxes(SHAPE, ORIGIN, DX, "cpu", max_fragments=2)
    boxes.fit(x, fragment, slack=2)
    lo, hi = _expected(x, fragment, 2, 2)
    assert hi[0].tolist() == [s - 1 for s in SHAPE], "the far fragment's box reaches the grid's last node"
    assert lo[1].tolist() == [0, 0, 0], "the near fragment's box starts at node 0"
    assert boxes.lo[:2].long().tolist() == lo.tolist()
    assert (boxes.lo[:2].long() + boxes.dims[:2].long() - 1).tolist() == hi.tolist()
