"""The fragment-aware overlap (`penetration.py`, DESIGN.md "Diagnostics") in a few Warp launches.

Space is cut into voxels of edge h. Each voxel belongs to the fragment with most particles in it
(ties: the smaller id); its erosion level is the number of steps it survives of

    alive_{s+1}(v) = alive_s(v) ∧ same(v) ∧ ⋀_{u ∈ N₆(v)} alive_s(u),     alive_0(v) = 1,

where same(v) says all six face neighbours u exist with v's owner. A particle of fragment a in a voxel
owned by b ≠ a at level L > 0 crosses into b by at least L·h. The torch twin (`overlap_packed`: sorted
keys, binary searches, two `unique` calls that each read a size back) gives the same numbers; here
two hash tables keyed by the voxel's integer coordinates replace the sorts, nothing is read back, and
a frame costs 13 launches instead of ≈ 60 torch ops and two device syncs (the linking launch takes the
first erosion step). On the CPU, where reading a flag costs no sync, the erosion stops at the first step
that leaves no voxel alive (the bread's pieces, less than a particle per voxel, erode away in two or
three of the eight steps).

Keys (int64, ≥ 0; −1 is empty): a voxel is (cx << 34) | (cy << 17) | cz with coordinates clamped to
[0, 2¹⁷); a (voxel, fragment) pair is voxel << 12 | fragment (fragment ids < 4096 = the largest
`sim.max_fragments`). Tables are open-addressing with linear probing at load ≤ ½.
"""

from __future__ import annotations

import torch
import warp as wp

from ...runtime import ensure_warp, warp_stream

wp.set_module_options({"enable_backward": False})

EMPTY = wp.constant(wp.int64(-1))
COORD_BITS = 17
FRAGMENT_BITS = 12
MAX_COORD = wp.constant((1 << COORD_BITS) - 1)
FRAGMENT_MASK = wp.constant(wp.int64((1 << FRAGMENT_BITS) - 1))
STEP_X = wp.constant(wp.int64(1 << (2 * COORD_BITS)))  # key offsets of one voxel along x and y (z: 1)
STEP_Y = wp.constant(wp.int64(1 << COORD_BITS))


@wp.func
def home(key: wp.int64, mask: int):
    """Fibonacci hashing: the table slot a key probes first."""
    h = wp.uint64(key) * wp.uint64(11400714819323198485)
    return int(h >> wp.uint64(33)) & mask


@wp.func
def probe(keys: wp.array(dtype=wp.int64), key: wp.int64, mask: int, create: bool):
    """The slot holding `key`; if it is absent, −1, or with `create` the slot it is inserted into by
    compare-and-swap (the table is never full)."""
    s = home(key, mask)
    for _probe in range(mask + 1):
        k = keys[s]
        if k == key:
            return s
        if k == EMPTY:
            if not create:
                return -1
            prev = wp.atomic_cas(keys, s, EMPTY, key)
            if prev == EMPTY or prev == key:
                return s
        s = (s + 1) & mask
    return -1


@wp.func
def voxel_coordinate(x: float, lo: wp.float64, h: wp.float64):
    """⌊(x − lo)/h⌋ + 1 in float64 as the torch twin computes it (a free layer of voxels below)."""
    d = wp.floor((wp.float64(x) - lo) / h)
    if not wp.isfinite(d):
        d = wp.float64(-1.0)
    d = wp.clamp(d, wp.float64(-1.0), wp.float64(MAX_COORD - 1))
    return wp.clamp(int(d) + 1, 0, MAX_COORD)


@wp.kernel
def clear_tables(
    pair_keys: wp.array(dtype=wp.int64),
    pair_count: wp.array(dtype=wp.int32),
    voxel_keys: wp.array(dtype=wp.int64),
    best: wp.array(dtype=wp.int64),
    level: wp.array(dtype=wp.int32),
):
    s = wp.tid()
    pair_keys[s] = EMPTY
    pair_count[s] = 0
    voxel_keys[s] = EMPTY
    best[s] = wp.int64(0)
    level[s] = 0


@wp.kernel
def bin_particles(
    x: wp.array(dtype=wp.vec3),
    fragment: wp.array(dtype=wp.int32),
    lo: wp.array(dtype=wp.float64),
    h: wp.float64,
    K: int,
    mask: int,
    pair_keys: wp.array(dtype=wp.int64),
    pair_count: wp.array(dtype=wp.int32),
    voxel_keys: wp.array(dtype=wp.int64),
    voxel_of: wp.array(dtype=int),
):
    """Count particles per (voxel, fragment); remember each particle's voxel slot (−1: unlabelled)."""
    i = wp.tid()
    f = fragment[i]
    if f < 0:
        voxel_of[i] = -1
        return
    f = wp.min(f, K - 1)
    p = x[i]
    cx = wp.int64(voxel_coordinate(p[0], lo[0], h))
    cy = wp.int64(voxel_coordinate(p[1], lo[1], h))
    v = cx * STEP_X + cy * STEP_Y + wp.int64(voxel_coordinate(p[2], lo[2], h))
    s = probe(pair_keys, (v << wp.int64(FRAGMENT_BITS)) | wp.int64(f), mask, True)
    wp.atomic_add(pair_count, s, 1)
    voxel_of[i] = probe(voxel_keys, v, mask, True)


@wp.kernel
def elect_owners(
    pair_keys: wp.array(dtype=wp.int64),
    pair_count: wp.array(dtype=wp.int32),
    voxel_keys: wp.array(dtype=wp.int64),
    mask: int,
    best: wp.array(dtype=wp.int64),
):
    """best[voxel] = max over its fragments of count << 12 | (4095 − fragment): most particles, then the
    smaller id."""
    s = wp.tid()
    k = pair_keys[s]
    if k == EMPTY:
        return
    v = probe(voxel_keys, k >> wp.int64(FRAGMENT_BITS), mask, False)
    f = k & FRAGMENT_MASK
    wp.atomic_max(best, v, (wp.int64(pair_count[s]) << wp.int64(FRAGMENT_BITS)) | (FRAGMENT_MASK - f))


@wp.func
def owner_of(best: wp.int64):
    return int(FRAGMENT_MASK - (best & FRAGMENT_MASK))


@wp.kernel
def link_neighbours(
    voxel_keys: wp.array(dtype=wp.int64),
    best: wp.array(dtype=wp.int64),
    mask: int,
    first_step: int,
    neighbour: wp.array2d(dtype=wp.int32),
    same: wp.array(dtype=wp.int32),
    alive: wp.array(dtype=wp.int32),
    level: wp.array(dtype=wp.int32),
):
    """The six face neighbours' slots, whether all six exist with this voxel's owner, and alive_0; with
    `first_step` alive_1 and its level instead, the first `erode` step: every voxel is alive_0, so a voxel
    survives it exactly when `same` (its six neighbours exist)."""
    s = wp.tid()
    k = voxel_keys[s]
    if k == EMPTY:
        alive[s] = 0
        return
    own = owner_of(best[s])
    ok = wp.int32(1)
    for j in range(6):
        axis = j // 2
        step = wp.int64(1)
        if axis == 0:
            step = STEP_X
        elif axis == 1:
            step = STEP_Y
        if j % 2 == 1:
            step = -step
        t = probe(voxel_keys, k + step, mask, False)
        neighbour[s, j] = t
        if t < 0:
            ok = 0
        elif owner_of(best[t]) != own:
            ok = 0
    same[s] = ok
    if first_step != 0:
        alive[s] = ok
        level[s] = ok
    else:
        alive[s] = 1


@wp.kernel
def erode(
    alive_in: wp.array(dtype=wp.int32),
    same: wp.array(dtype=wp.int32),
    neighbour: wp.array2d(dtype=wp.int32),
    alive_out: wp.array(dtype=wp.int32),
    level: wp.array(dtype=wp.int32),
):
    """One erosion step, alive_{s+1} from alive_s; level counts the steps a voxel survived."""
    s = wp.tid()
    a = wp.int32(0)
    if alive_in[s] != 0 and same[s] != 0:
        a = 1
        for j in range(6):
            if alive_in[neighbour[s, j]] == 0:
                a = 0
    alive_out[s] = a
    level[s] = level[s] + a


@wp.kernel
def score_particles(
    fragment: wp.array(dtype=wp.int32),
    voxel_of: wp.array(dtype=int),
    best: wp.array(dtype=wp.int64),
    level: wp.array(dtype=wp.int32),
    h: wp.float64,
    K: int,
    out: wp.array(dtype=wp.float64),
):
    """A particle inside another fragment's eroded voxel: count it, its depth level·h into the maximum
    and into its pair's (a·K + b) maximum. Only crossing particles touch `out`."""
    i = wp.tid()
    s = voxel_of[i]
    if s < 0:
        return
    f = wp.min(fragment[i], K - 1)
    own = owner_of(best[s])
    lev = level[s]
    if lev > 0 and own != f:
        depth = wp.float64(lev) * h
        wp.atomic_add(out, 0, wp.float64(1.0))
        wp.atomic_max(out, 1, depth)
        wp.atomic_max(out, 2 + f * K + own, depth)


class VoxelOverlap:
    """Reusable tables for `packed` (sized for up to `n` particles on `device`)."""

    def __init__(self, n: int, device):
        ensure_warp()
        self.device = str(device)
        cap = 1024
        while cap < 2 * max(n, 1):
            cap *= 2
        self.n, self.capacity = n, cap
        t = {"device": self.device}
        self.pair_keys = torch.empty(cap, dtype=torch.int64, **t)
        self.pair_count = torch.empty(cap, dtype=torch.int32, **t)
        self.voxel_keys = torch.empty(cap, dtype=torch.int64, **t)
        self.best = torch.empty(cap, dtype=torch.int64, **t)
        self.level = torch.empty(cap, dtype=torch.int32, **t)
        self.same = torch.empty(cap, dtype=torch.int32, **t)
        self.alive = [torch.empty(cap, dtype=torch.int32, **t) for _ in range(2)]
        self.neighbour = torch.empty((cap, 6), dtype=torch.int32, **t)
        self.voxel_of = torch.empty(n, dtype=torch.int32, **t)
        self.w = {
            k: wp.from_torch(getattr(self, k))
            for k in ("pair_keys", "pair_count", "voxel_keys", "best", "level", "same", "neighbour", "voxel_of")
        }
        self.w["alive"] = [wp.from_torch(a) for a in self.alive]

    def packed(self, x: torch.Tensor, fragment: torch.Tensor, h: float, K: int, max_depth: int = 8) -> torch.Tensor:
        """[2 + K·K] float64 on x's device: crossing count, max depth [m], depth [m] of fragment a inside b
        at 2 + a·K + b (the layout of the twin `penetration.overlap_packed`); no host read on a GPU (on the CPU
        the erosion reads whether a voxel is still alive).
        x [N, 3] float32, fragment [N] int32 (−1: unlabelled), K ≤ 4096."""
        out = torch.zeros(2 + K * K, dtype=torch.float64, device=x.device)
        n = x.shape[0]
        if K < 2 or n == 0:
            return out
        if n > self.n or K > (1 << FRAGMENT_BITS):
            raise ValueError(f"VoxelOverlap holds {self.n} particles and 4096 fragments; got {n} and {K}")
        ok = (fragment >= 0)[:, None]
        lo = torch.where(ok, x, float("inf")).min(0).values.double()  # [3]
        lo = torch.where(torch.isfinite(lo), lo, torch.zeros_like(lo))
        w, cap, mask = self.w, self.capacity, self.capacity - 1
        d, stream = self.device, warp_stream(self.device)
        hh = float(h)

        def launch(kernel, dim, inputs):
            wp.launch(kernel, dim=dim, inputs=inputs, device=d, stream=stream)

        launch(clear_tables, cap, [w["pair_keys"], w["pair_count"], w["voxel_keys"], w["best"], w["level"]])
        xw = wp.from_torch(x.contiguous(), dtype=wp.vec3)
        fw = wp.from_torch(fragment.to(torch.int32).contiguous())
        lw = wp.from_torch(lo.contiguous())
        tables = [w["pair_keys"], w["pair_count"], w["voxel_keys"], w["voxel_of"]]
        launch(bin_particles, n, [xw, fw, lw, hh, K, mask, *tables])
        launch(elect_owners, cap, [w["pair_keys"], w["pair_count"], w["voxel_keys"], mask, w["best"]])
        first = int(max_depth > 0)  # step 0 of the erosion in the linking launch
        links = [w["voxel_keys"], w["best"], mask, first, w["neighbour"], w["same"], w["alive"][first], w["level"]]
        launch(link_neighbours, cap, links)
        for step in range(first, max_depth):
            if d == "cpu" and int(self.alive[step % 2].amax()) == 0:  # flags 0 or 1: amax costs a tenth of any
                break  # no voxel alive: the steps left add 0 to every level (on the CPU the read waits for nothing)
            a, b = w["alive"][step % 2], w["alive"][(step + 1) % 2]
            launch(erode, cap, [a, w["same"], w["neighbour"], b, w["level"]])
        launch(score_particles, n, [fw, w["voxel_of"], w["best"], w["level"], hh, K, wp.from_torch(out)])
        return out
