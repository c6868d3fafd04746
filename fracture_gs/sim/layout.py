"""The grid's storage layout and the solver's statistics indices: one owner for both.

Storage ("second fields only where fragments share support", DESIGN.md): every quantity keeps
both slots in one buffer, so a kernel reaches field k at a node with one index. Nodes
[0, X·Y·Z) are slot 0, dense over the grid; the next |S| entries are slot 1 on the shared box
S = B⁰ ∩ B¹ of the two fields' node boxes. Field 0 always sits in slot 0; field 1 sits in slot 1
on S and in slot 0 elsewhere, where no fragment-0 particle reaches (`slot_index`). Boxes are
(lo, hi) node ranges, hi exclusive.

`grid.py` allocates this layout, `transfer.py` indexes it in its kernels, `diagnostics.py` reads
the statistics; none of them defines either.
"""
from __future__ import annotations

import warp as wp

EMPTY_BOX = (0, 0, 0, 0, 0, 0)

# contact statistics accumulated by the grid update (indices into Grid.contact_stats)
STAT_GATED, STAT_PROJECTED, STAT_DPX, STAT_DPY, STAT_DPZ, STAT_PNORM, STAT_UN_AFTER, STAT_DVT, STAT_FIRST_T = range(9)
N_STATS = 9
NEVER = 1e30  # STAT_FIRST_T before any contact


def box_intersection(a: tuple, b: tuple) -> tuple:
    """Intersection of two node boxes (lo, hi), or EMPTY_BOX."""
    box = tuple(max(a[i], b[i]) for i in range(3)) + tuple(min(a[i], b[i]) for i in range(3, 6))
    return box if all(box[i + 3] > box[i] for i in range(3)) else EMPTY_BOX


def box_volume(box: tuple) -> int:
    return max(0, box[3] - box[0]) * max(0, box[4] - box[1]) * max(0, box[5] - box[2])


@wp.func
def inside(node: wp.vec3i, lo: wp.vec3i, hi: wp.vec3i):
    return node[0] >= lo[0] and node[0] < hi[0] and node[1] >= lo[1] and node[1] < hi[1] and node[2] >= lo[2] and node[2] < hi[2]


@wp.func
def flat(node: wp.vec3i, lo: wp.vec3i, dims: wp.vec3i):
    d = node - lo
    return (d[0] * dims[1] + d[1]) * dims[2] + d[2]


@wp.func
def slot_index(node: wp.vec3i, k: int, shape: wp.vec3i, s_lo: wp.vec3i, s_hi: wp.vec3i):
    """Storage index of field k at `node` (layout in `grid.py`): slot 1, after slot 0's X·Y·Z
    nodes, for field 1 on S; slot 0 otherwise. Branch-free, so one load or atomic serves both."""
    on_s = k == 1 and inside(node, s_lo, s_hi)
    i1 = shape[0] * shape[1] * shape[2] + flat(node, s_lo, s_hi - s_lo)
    return wp.where(on_s, i1, flat(node, wp.vec3i(0, 0, 0), shape))
