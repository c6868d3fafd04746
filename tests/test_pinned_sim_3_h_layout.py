"""`sim/layout.py` node boxes: a box (lo, hi) holds nodes lo ≤ node < hi on every axis (hi exclusive), so its
node count is the product of its extents and a box that is empty along any one axis holds no node; the
intersection of two boxes is empty when they only touch. `inside` (a `@wp.func`, driven from a kernel here) is
the membership test of the escape checks: a particle's stencil that reaches node hi on any axis has left the
box."""

import torch
import warp as wp

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.grid.layout import box_volume, pool_capacity
from fracture_gs.sim.stencil import flat, inside, unflat

ensure_warp()


@wp.kernel
def _inside(nodes: wp.array(dtype=wp.vec3i), lo: wp.vec3i, hi: wp.vec3i, out: wp.array(dtype=wp.int32)):
    i = wp.tid()
    out[i] = wp.where(inside(nodes[i], lo, hi), 1, 0)


@wp.kernel
def _flat(nodes: wp.array(dtype=wp.vec3i), lo: wp.vec3i, dims: wp.vec3i, out: wp.array(dtype=wp.vec4i)):
    i = wp.tid()
    n = flat(nodes[i], lo, dims)
    back = unflat(n, dims) + lo
    out[i] = wp.vec4i(n, back[0], back[1], back[2])


def test_inside_holds_lo_and_excludes_hi_on_every_axis():
    """Box lo = (2, 3, 4), hi = (5, 7, 9): for each axis, nodes at lo and hi − 1 (the others in the middle) are
    inside, lo − 1 and hi are not."""
    lo, hi, mid = (2, 3, 4), (5, 7, 9), (3, 5, 6)
    nodes, want = [], []
    for a in range(3):
        for value, ok in ((lo[a], 1), (hi[a] - 1, 1), (lo[a] - 1, 0), (hi[a], 0)):
            node = list(mid)
            node[a] = value
            nodes.append(node)
            want.append(ok)
    n = wp.from_torch(torch.tensor(nodes, dtype=torch.int32), dtype=wp.vec3i)
    out = wp.zeros(len(nodes), dtype=wp.int32, device="cpu")
    wp.launch(_inside, dim=len(nodes), inputs=[n, wp.vec3i(*lo), wp.vec3i(*hi), out], device="cpu")
    assert out.numpy().tolist() == want


def test_flat_index_is_row_major_in_the_box_and_unflat_inverts_it():
    """A box from lo = (1, 2, 3) with dims (4, 5, 6): node lo is 0, the last node lo + dims − 1 is 119, a step
    along z is 1, along y 6, along x 30; `unflat` gives the offset back."""
    lo, dims = (1, 2, 3), (4, 5, 6)
    nodes = [(1, 2, 3), (4, 6, 8), (1, 2, 4), (1, 3, 3), (2, 2, 3), (3, 4, 5)]
    n = wp.from_torch(torch.tensor(nodes, dtype=torch.int32), dtype=wp.vec3i)
    out = wp.zeros(len(nodes), dtype=wp.vec4i, device="cpu")
    wp.launch(_flat, dim=len(nodes), inputs=[n, wp.vec3i(*lo), wp.vec3i(*dims), out], device="cpu")
    got = out.numpy().tolist()
    assert [g[0] for g in got] == [0, 119, 1, 6, 30, 2 * 30 + 2 * 6 + 2]
    assert [tuple(g[1:]) for g in got] == nodes


def test_box_volume_counts_nodes_and_is_zero_when_any_axis_is_empty():
    """(0..3) × (1..5) × (2..4): 3 · 4 · 2 = 24 nodes; a box with hi = lo on any one axis, or hi < lo, holds
    none (no negative or one-node count from the empty axis)."""
    assert box_volume((0, 1, 2, 3, 5, 4)) == 24
    for a in range(3):
        box = [0, 1, 2, 3, 5, 4]
        box[3 + a] = box[a]
        assert box_volume(tuple(box)) == 0, a
        box[3 + a] = box[a] - 2
        assert box_volume(tuple(box)) == 0, a
    assert box_volume((0, 0, 0, 0, 0, 0)) == 0


def test_pool_capacity_is_a_power_of_two_at_least_twice_the_rows():
    """Pool rows: at least 256, else the next power of two of twice the expected rows (128 rows fit 256, 129
    need 512)."""
    assert [pool_capacity(r) for r in (0, 1, 128, 129, 256, 257, 1000)] == [256, 256, 256, 512, 512, 1024, 2048]
