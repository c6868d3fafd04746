"""The surface measure (`penetration.surface_depth`) in Warp: the kernel sums behind other pieces' surfaces and their
depth inversion, one launch each, nothing read back.

Sums: for a query particle p of piece a, c_b(p) = Σ_{j∈b, b≠a} J_j W(|x_p − x_j|) / n_b over every particle within
the kernel radius R (W the compact kernel of `penetration.kernel`, J_j its volume change det F, n_b b's filled
density). The torch twin (`penetration.behind_surfaces_torch`) materialises every (query, particle) pair of the
cells around the queries — about a million pairs a frame for pieces pressed together, 60 ms a frame on one CPU
core and ≈ 60 ops a chunk on a GPU. Here one thread per query walks the same cells (a binary search in the sorted
cell keys where a run of cells along z starts, a step along the keys for each next one; cells of its own piece alone
skipped), in the same order, and sums in float64 (the twin takes the pair offsets in float32, so the two agree to
about 1e-6 of a share). The same thread then inverts each share over ½ (below, the particle is in front of b's
surface) and keeps the deepest: depth [m] and the piece it lies behind.

Inversion:
a particle whose ball of radius R is filled to a share c by another piece lies d = R·u behind that piece's flat
surface, where u solves F(u) = c for the kernel's half-space share

    F(u) = 1/2 + 35/32 · (u − u³ + 3u⁵/5 − u⁷/7),    u ∈ [−1, 1],

monotone in u. `penetration.depth_from_fraction` is the torch twin: 40 halvings of [−1, 1], about 600 elementwise
ops, each a launch on a GPU. Here each thread halves its own interval 40 times: the same bisection and the same
polynomial. The two agree to within rounding (the powers may round differently by an ulp, which moves u by about
that much; `tests/test_penetration_kernels.py`).
"""

from __future__ import annotations

import math

import torch
import warp as wp

from ...runtime import ensure_warp, warp_stream

wp.set_module_options({"enable_backward": False})

HALVINGS = 40  # [−1, 1] halved 40 times: u to 2⁻⁴⁰


@wp.func
def half_space_share(u: wp.float64):
    """F(u) for u in [−1, 1]: the share of the kernel W ∝ (1 − r²/R²)² behind a flat face u·R in front of its centre."""
    u3 = u * u * u
    return wp.float64(0.5) + wp.float64(35.0 / 32.0) * (
        u - u3 + wp.float64(0.6) * wp.pow(u, wp.float64(5.0)) - wp.pow(u, wp.float64(7.0)) / wp.float64(7.0)
    )


@wp.func
def invert_share(c: wp.float64):
    """u in [−1, 1] with F(u) = c (c clamped to [0, 1]): 40 halvings of [−1, 1]."""
    c = wp.clamp(c, wp.float64(0.0), wp.float64(1.0))
    lo = wp.float64(-1.0)
    hi = wp.float64(1.0)
    for _halving in range(HALVINGS):
        mid = wp.float64(0.5) * (lo + hi)
        if half_space_share(mid) < c:
            lo = mid
        else:
            hi = mid
    return wp.float64(0.5) * (lo + hi)


@wp.func
def lower_bound(keys: wp.array(dtype=wp.int64), key: wp.int64):
    """The first index of the sorted `keys` not below `key` (len(keys) if none)."""
    lo = int(0)  # noqa: UP018 - a typed variable Warp may change in the loop
    hi = keys.shape[0]
    while lo < hi:
        mid = (lo + hi) // 2
        if keys[mid] < key:
            lo = mid + 1
        else:
            hi = mid
    return lo


@wp.func
def lower_bound_next(keys: wp.array(dtype=wp.int64), key: wp.int64, last_key: wp.int64, last: int, have: int):
    """`lower_bound`(keys, key) given last = `lower_bound`(keys, last_key) when `have` (keys sorted and unique): where
    key = last_key + 1 (the next cell along z) it is last, one further if keys[last] is last_key itself; else a
    binary search."""
    i = int(0)  # noqa: UP018 - a typed variable Warp may change in the branches
    if have != 0 and key == last_key + wp.int64(1):
        i = last
        if last < keys.shape[0]:
            if keys[last] == last_key:
                i = last + 1
    else:
        i = lower_bound(keys, key)
    return i


@wp.func
def cell_key(cx: wp.int64, cy: wp.int64, cz: wp.int64, bits: int):
    """The sorted key of cell (cx, cy, cz), as `penetration._keys`."""
    return (cx << wp.int64(2 * bits)) | (cy << wp.int64(bits)) | cz


@wp.func
def distance_sq(x: wp.array2d(dtype=wp.float64), p: wp.int64, j: wp.int64):
    """|x_p − x_j|² [m²]."""
    dx = x[p, 0] - x[j, 0]
    dy = x[p, 1] - x[j, 1]
    dz = x[p, 2] - x[j, 2]
    return dx * dx + dy * dy + dz * dz


@wp.kernel
def deepest_behind(
    query: wp.array(dtype=wp.int64),  # [M] particle indices
    coord: wp.array2d(dtype=wp.int64),  # [N, 3] cell coordinates (cells of edge R/3)
    offsets: wp.array2d(dtype=wp.int64),  # [C, 3] the cells within reach of a cell
    keys: wp.array(dtype=wp.int64),  # [V] sorted occupied cell keys
    start: wp.array(dtype=wp.int64),  # [V] first sorted index of each cell
    count: wp.array(dtype=wp.int64),  # [V]
    fmin: wp.array(dtype=wp.int64),  # [V] smallest / largest fragment id in each cell
    fmax: wp.array(dtype=wp.int64),
    order: wp.array(dtype=wp.int64),  # [N] particle index of each sorted slot
    x: wp.array2d(dtype=wp.float64),  # [N, 3] positions [m]
    frag: wp.array(dtype=wp.int64),  # [N] fragment id, −1: not evaluated
    volume_ratio: wp.array(dtype=wp.float64),  # [N] det F
    filled: wp.array(dtype=wp.float64),  # [K] each piece's filled density [1/m³]
    radius: wp.float64,
    norm: wp.float64,  # 105 / (32π R³), W's value at its centre
    bits: int,
    sums: wp.array2d(dtype=wp.float64),  # [M, K] scratch, zero on entry
    depth: wp.array(dtype=wp.float64),  # [M] out: deepest depth [m], 0 if behind none
    into: wp.array(dtype=wp.int64),  # [M] out: the piece it lies behind (largest id among equals), −1 if none
):
    m = wp.tid()
    p = query[m]
    fp = frag[p]
    r2 = radius * radius
    last_key = wp.int64(0)
    last = int(0)  # noqa: UP018 - a typed variable Warp may change in the loop
    for c in range(offsets.shape[0]):
        key = cell_key(coord[p, 0] + offsets[c, 0], coord[p, 1] + offsets[c, 1], coord[p, 2] + offsets[c, 2], bits)
        i = lower_bound_next(keys, key, last_key, last, c)  # offsets run along z: mostly one step, not a search
        last_key = key
        last = i
        if i < keys.shape[0]:
            if keys[i] == key and not (fmin[i] == fmax[i] and fmin[i] == fp):
                for s in range(int(start[i]), int(start[i] + count[i])):
                    j = order[s]
                    fj = frag[j]
                    if fj >= wp.int64(0) and fj != fp:
                        u2 = distance_sq(x, p, j) / r2
                        if u2 < wp.float64(1.0):
                            t = wp.float64(1.0) - u2
                            sums[m, int(fj)] += norm * t * t / filled[int(fj)] * volume_ratio[j]
    best = wp.float64(0.0)
    which = wp.int64(-1)
    for b in range(sums.shape[1]):
        share = sums[m, b]
        if share > wp.float64(0.5):  # behind b's surface only where b fills over half
            d = radius * invert_share(share)
            if d > wp.float64(0.0) and d >= best:
                best = d
                which = wp.int64(b)
    depth[m] = best
    into[m] = which


@wp.kernel
def near_another_piece(
    query: wp.array(dtype=wp.int64),  # [M] particle indices
    coord: wp.array2d(dtype=wp.int64),  # [N, 3] cell coordinates (cells of edge `reach`)
    keys: wp.array(dtype=wp.int64),  # [V] sorted occupied cell keys
    start: wp.array(dtype=wp.int64),  # [V]
    count: wp.array(dtype=wp.int64),  # [V]
    order: wp.array(dtype=wp.int64),  # [N]
    x: wp.array2d(dtype=wp.float64),  # [N, 3] positions [m]
    frag: wp.array(dtype=wp.int64),  # [N] fragment id, −1: none
    reach2: wp.float64,  # squared distance [m²]
    bits: int,
    near: wp.array(dtype=wp.int32),  # [M] out: 1 if a particle of another piece is closer than √reach2
):
    m = wp.tid()
    p = query[m]
    fp = frag[p]
    found = int(0)  # noqa: UP018 - a typed variable Warp may change in the loop
    for ox in range(-1, 2):
        for oy in range(-1, 2):
            last_key = wp.int64(0)
            last = int(0)  # noqa: UP018 - a typed variable Warp may change in the loop
            have = int(0)  # noqa: UP018 - set once a cell of this column was looked up
            for oz in range(-1, 2):
                if found == 0:  # once found, the remaining cells change nothing
                    key = cell_key(
                        coord[p, 0] + wp.int64(ox), coord[p, 1] + wp.int64(oy), coord[p, 2] + wp.int64(oz), bits
                    )
                    i = lower_bound_next(keys, key, last_key, last, have)  # a search, then steps along z
                    last_key = key
                    last = i
                    have = 1
                    if i < keys.shape[0]:
                        if keys[i] == key:
                            for s in range(int(start[i]), int(start[i] + count[i])):
                                j = order[s]
                                fj = frag[j]
                                if fj >= wp.int64(0) and fj != fp and distance_sq(x, p, j) < reach2:
                                    found = 1
    near[m] = found


def _view(t: torch.Tensor):
    """A launch argument over t's memory (a contiguous copy where t is not): the bare array descriptor, which is
    cheaper to make than a `wp.array` and keeps t alive."""
    return wp.from_torch(t.contiguous(), return_ctype=True)


def near_another_piece_mask(
    x: torch.Tensor, frag: torch.Tensor, cells, query: torch.Tensor, reach: float, bits: int
) -> torch.Tensor:  # -> [M] bool
    """Which query particles have a particle of another piece (id ≥ 0) closer than `reach` [m]: one thread per query
    walks the 27 cells around its own (`cells` a `penetration._Cells` of edge ≥ reach over x [N, 3] float64, frag
    [N] int64). The twin is the torch gather in `penetration.surface_depth(twin=True)`."""
    near = torch.zeros(query.numel(), dtype=torch.int32, device=x.device)
    if query.numel() == 0:
        return near.bool()
    ensure_warp()
    device = str(x.device)
    inputs = [query, cells.coord, cells.keys, cells.start, cells.count, cells.order, x, frag]
    wp.launch(
        near_another_piece,
        dim=query.numel(),
        inputs=[_view(t) for t in inputs] + [reach * reach, bits, _view(near)],
        device=device,
        stream=warp_stream(device),
    )
    return near.bool()


def deepest_behind_surfaces(
    x: torch.Tensor,
    frag: torch.Tensor,
    volume_ratio: torch.Tensor,
    filled: torch.Tensor,
    radius: float,
    cells,
    offsets: torch.Tensor,
    query: torch.Tensor,
    bits: int,
    chunk: int,
) -> tuple[torch.Tensor, torch.Tensor]:
    """(depth [M] float64 [m], into [M] int64) of each query particle behind the other pieces' surfaces (see the
    module's docstring; `penetration.behind_surfaces_torch` is the twin). x [N, 3] float64, frag [N] int64 (−1: not
    evaluated), volume_ratio [N] float64, filled [K] float64, `cells` a `penetration._Cells` of edge R/3 over x,
    offsets [C, 3] int64 the cells around a cell to visit, query [M] int64; at most `chunk` queries' [chunk, K]
    sums at a time."""
    K, M = filled.numel(), query.numel()
    dev = x.device
    depth = torch.zeros(M, dtype=torch.float64, device=dev)
    into = torch.full((M,), -1, dtype=torch.long, device=dev)
    if M == 0 or K == 0:
        return depth, into
    ensure_warp()
    device = str(dev)
    w = {
        k: _view(t)
        for k, t in dict(
            keys=cells.keys, start=cells.start, count=cells.count, fmin=cells.fmin, fmax=cells.fmax,
            order=cells.order, frag=frag, volume_ratio=volume_ratio, filled=filled,
        ).items()
    }  # fmt: skip
    coord, off, xs = (_view(t) for t in (cells.coord, offsets, x))
    norm = 105.0 / (32.0 * math.pi * radius**3)
    for s in range(0, M, chunk):
        q = query[s : s + chunk].contiguous()
        sums = torch.zeros(q.numel(), K, dtype=torch.float64, device=dev)
        wp.launch(
            deepest_behind,
            dim=q.numel(),
            inputs=[
                _view(q), coord, off, w["keys"], w["start"], w["count"], w["fmin"], w["fmax"], w["order"],
                xs, w["frag"], w["volume_ratio"], w["filled"], radius, norm, bits, _view(sums),
                _view(depth[s : s + chunk]), _view(into[s : s + chunk]),
            ],
            device=device,
            stream=warp_stream(device),
        )  # fmt: skip
    return depth, into


@wp.kernel
def invert_half_space_share(share: wp.array(dtype=wp.float64), u: wp.array(dtype=wp.float64)):
    """u[i] with F(u[i]) = share[i] (clamped to [0, 1])."""
    i = wp.tid()
    u[i] = invert_share(share[i])


def depth_from_share(share: torch.Tensor) -> torch.Tensor:  # [E] float64 -> [E] float64 in [−1, 1]
    """u with F(u) = share (`penetration.depth_from_fraction`'s twin), on share's device, in one launch."""
    share = share.to(torch.float64).contiguous()
    u = torch.empty_like(share)
    if share.numel() == 0:
        return u
    ensure_warp()
    device = str(share.device)
    wp.launch(
        invert_half_space_share,
        dim=share.numel(),
        inputs=[wp.from_torch(share), wp.from_torch(u)],
        device=device,
        stream=warp_stream(device),
    )
    return u
