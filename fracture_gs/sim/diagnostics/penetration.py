"""Fragment-aware penetration, measured between the pieces themselves (DESIGN.md "Diagnostics").

The paper's columns measure crossing along the latched normal n_Π, which misreads a piece that
tumbles (Table 4, Panel A). Two measures between the pieces live here.

`surface_depth` (the diagnostics' `fragment_penetration`): how far a particle of fragment a lies behind
fragment b's surface, continuously. Around a particle p, b's volume fraction
c_b(p) = Σ_{j∈b} V_j W(|x_p − x_j|), with the compact kernel W(r) = 105/(32πR³)·(1 − r²/R²)² (∫W = 1), is
the share of the ball of radius R around p that b fills. Where b's surface is locally flat that share is
F(d/R), d the signed depth of p behind the surface and F the kernel's half-space share
(`fraction_of_half_space`, a polynomial), so d = R·F⁻¹(c_b). The particles sample each piece's volume
uniformly, so c_b is an unbiased estimate of the true share whatever the particles' lattice or jitter; the
kernel averages the sampling noise. R is SPACINGS particle spacings; depths beyond R read R (a lower
bound). Only particles in cells next to another fragment's particles are evaluated (sorted cell keys,
binary searches, no dense grid), in chunks.

`fragment_overlap` / `overlap_packed` (the diagnostics' `voxel_crossing`, `voxel_penetration`): space
cut into voxels of edge h ≈ 0.6 Δx, each owned by the fragment with most particles in it and eroded once
(a voxel counts when its six face neighbours have the same owner); a particle inside another fragment's
eroded voxels crosses, by the number of erosions its voxel survives times h. Its depth comes in steps
of h: one voxel (0.6 Δx) is its smallest non-zero reading, which an isolated particle at an oblique
face can give with no overlap at all. Kept as the cheap, graph-recordable occupancy check
(`overlap_kernels.py` runs it in Warp launches).
"""

from __future__ import annotations

import math
from typing import Callable, Optional, Union

import torch

from .penetration_kernels import deepest_behind_surfaces, near_another_piece_mask

_NEIGHBOURS = ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1))


_OFFSETS: dict = {}


def _neighbour_offsets(device) -> torch.Tensor:  # [6, 3] int64, made once per device
    key = str(device)
    if key not in _OFFSETS:
        _OFFSETS[key] = torch.tensor(_NEIGHBOURS, dtype=torch.long, device=device)
    return _OFFSETS[key]


def overlap_packed(x: torch.Tensor, fragment: torch.Tensor, h: float, K: int, max_depth: int = 8) -> torch.Tensor:
    """`fragment_overlap` as one device tensor [2 + K·K] float64 — (crossing count, max depth [m],
    depth [m] of fragment a inside b at a·K + b) — with no host read but the two `unique` sizes, so a
    per-frame tracker packs it with its other numbers and reads them once. K: number of fragment ids."""
    out = torch.zeros(2 + K * K, dtype=torch.float64, device=x.device)
    if K < 2 or x.numel() == 0:
        return out
    ok = fragment >= 0
    frag = torch.where(ok, fragment.long(), torch.zeros_like(fragment, dtype=torch.long)).clamp_max(K - 1)
    xd = x.double()
    lo = torch.where(ok[:, None], xd, torch.full_like(xd, float("inf"))).min(0).values
    lo = torch.where(torch.isfinite(lo), lo, torch.zeros_like(lo))
    cell = (torch.floor((xd - lo) / h).long() + 1).clamp(0, 1 << 20)  # a free layer of voxels around
    dims = cell.max(0).values + 2
    stride = torch.stack([dims[1] * dims[2], dims[2], torch.ones_like(dims[2])])
    vox = torch.where(ok, (cell * stride).sum(1), torch.full_like(frag, -1))  # [N], −1 for unlabelled
    pairs, counts = torch.unique(vox * K + frag, return_counts=True)  # sorted (voxel, fragment) keys
    counts = torch.where(pairs >= 0, counts, torch.zeros_like(counts))
    vox_of = torch.div(pairs, K, rounding_mode="floor")
    voxels, inverse = torch.unique_consecutive(vox_of, return_inverse=True)
    best = torch.zeros(voxels.numel(), dtype=counts.dtype, device=x.device).scatter_reduce(0, inverse, counts, "amax")
    top = (counts == best[inverse]) & (counts > 0)
    idx = torch.arange(pairs.numel(), device=x.device)
    winner = torch.full((voxels.numel(),), pairs.numel(), dtype=torch.long, device=x.device)
    winner = winner.scatter_reduce(0, inverse, torch.where(top, idx, torch.full_like(idx, pairs.numel())), "amin")
    valid = winner < pairs.numel()
    occ = torch.where(valid, pairs[winner.clamp_max(pairs.numel() - 1)], torch.full_like(voxels, -1))  # (voxel, owner)
    # erosion by levels without compaction: a voxel survives a step when its six neighbours have the
    # same owner and survived the previous step
    alive = valid & (voxels >= 0)
    level = torch.zeros(occ.numel(), dtype=torch.long, device=x.device)
    last = occ.numel() - 1
    steps = (_neighbour_offsets(x.device) * stride).sum(1) * K  # [6] key offsets of the face neighbours
    wanted = occ[None, :] + steps[:, None]  # [6, V]: the neighbour's key if it has the same owner
    js = torch.searchsorted(occ, wanted.reshape(-1)).clamp_max(last).view(6, -1)  # [6, V] neighbours
    same = (occ[js] == wanted).all(0)  # all six there, same owner
    cpu = x.device.type == "cpu"
    for _ in range(max_depth):
        alive = alive & same & alive[js].all(0)
        level += alive.long()
        if cpu and not bool(alive.any()):  # nothing left to erode (a free host read on the CPU only)
            break
    # each particle against its voxel's owner and level
    v = torch.searchsorted(voxels, vox).clamp_max(voxels.numel() - 1)
    owner = torch.remainder(occ[v], K)
    depth = level[v].double() * h
    foreign = ok & (voxels[v] == vox) & (level[v] > 0) & (owner != frag)
    depth = torch.where(foreign, depth, torch.zeros_like(depth))
    out[0] = foreign.sum()
    out[1] = depth.max()
    rows = 256 if x.is_cuda else 1  # partial maxima (particle index mod rows): no atomics on a few addresses
    pair = (torch.arange(x.shape[0], device=x.device) % rows) * (K * K) + frag * K + owner
    out[2:] = (
        torch.zeros(rows * K * K, dtype=torch.float64, device=x.device)
        .scatter_reduce(0, pair, depth, "amax")
        .view(rows, K * K)
        .amax(0)
    )
    return out


def unpack_overlap(values: list, K: int) -> dict:
    """The dict of `fragment_overlap` from the host copy of an `overlap_packed` tensor."""
    pairs = {(k // K, k % K): v for k, v in enumerate(values[2 : 2 + K * K]) if v > 0}
    return {"crossing": int(values[0]), "depth": float(values[1]), "pairs": pairs}


def fragment_overlap(x: torch.Tensor, fragment: torch.Tensor, h: float, max_depth: int = 8) -> dict:
    """Particles of one fragment inside another's occupied volume.

    x [N,3], fragment [N] (ids ≥ 0). Returns {"crossing": count, "depth": max depth [m] (0 if none),
    "pairs": {(a, b): max depth [m]} for fragment a inside b}."""
    K = int(fragment.max()) + 1 if fragment.numel() else 0
    if K < 2:
        return {"crossing": 0, "depth": 0.0, "pairs": {}}
    return unpack_overlap(overlap_packed(x, fragment, h, K, max_depth).tolist(), K)


# ---- the continuous measure -------------------------------------------------------------------------

SPACINGS = 6.0  # kernel radius R in particle spacings s: depth noise ≈ s·(s/R)^1.5 (DESIGN.md)
NEAR = 1.2  # spacings: particles with one of another fragment this close are evaluated
CHUNK = 4096  # candidates per chunk: ≈ 2,000 particles gathered each, so ≈ 8 M pairs at a time
DENSE_LIMIT = 1 << 22  # (candidate, fragment) sums kept dense up to this many entries, else sorted keys
_BITS = 21  # bits per axis of a cell key
DENSE_CELLS = 1 << 22  # `_Cells.near_foreign` pools a dense grid up to this many cells (16 MiB an int32 copy)
NN_PER_SPACING = 0.65  # median nearest-neighbour distance over h of a jittered grid (one point anywhere per cell h)
SAMPLES = 256  # particles per fragment whose own kernel sums calibrate its filled density
CENTRED = 0.01  # a sample whose neighbours' kernel-weighted centroid lies within this × R sees a full ball
DENSITY_REACH = 4.0  # radius of the small density ball in nearest-neighbour distances (≈ 2.6 spacings)
SMALL_CENTRED = 0.1  # its centroid test (fewer neighbours, more noise: a face particle's is ≈ 0.3)
ISOTROPY = 0.8  # and its neighbours' second moment at least this round (smallest / largest eigenvalue)
SMALL_TRUST = 0.97  # the small ball's density is trusted to 3 %: below it a piece's own full-ball sum wins


def _keys(c: torch.Tensor) -> torch.Tensor:  # [..., 3] int64 cell coordinates -> [...] int64 keys
    return (c[..., 0] << (2 * _BITS)) | (c[..., 1] << _BITS) | c[..., 2]


def _cube(reach: int, device, ball: bool = False) -> torch.Tensor:  # [C, 3] int64 offsets around a cell
    """The (2·reach + 1)³ cell offsets; with `ball` only those a point of the centre cell can see within
    reach cells (the cube's corners dropped)."""
    r = torch.arange(-reach, reach + 1, device=device)
    off = torch.stack(torch.meshgrid(r, r, r, indexing="ij"), -1).reshape(-1, 3)
    if ball:
        off = off[((off.abs() - 1).clamp_min(0) ** 2).sum(1) < reach * reach]
    return off


def _max_around(grid: torch.Tensor) -> torch.Tensor:  # [C, d0 + 2, d1 + 2, d2 + 2] -> [C, d0, d1, d2]
    """Per channel, the largest value over each interior cell's 3×3×3 block, one axis at a time (exact: a maximum
    of maxima, as `max_pool3d` with padding; the outer layer stands for the padding and must hold the least value)."""
    for dim in (3, 2, 1):
        n = grid.shape[dim] - 2
        grid = torch.maximum(torch.maximum(grid.narrow(dim, 0, n), grid.narrow(dim, 1, n)), grid.narrow(dim, 2, n))
    return grid


def _mixed_around(c: torch.Tensor, fmin: torch.Tensor, fmax: torch.Tensor) -> Optional[torch.Tensor]:  # [n] bool
    """For entries in cells c [n, 3] (int64, repeats allowed) with ids fmin ≤ fmax [n]: whether the smallest and
    largest id over the entry's cell and its 26 neighbours differ. As two 3×3×3 max-pools (of the ids and of their
    negatives) of a dense int32 grid over the cells' bounding box, empty cells holding the least int32, which changes
    neither extreme; None when the box has more than DENSE_CELLS cells or an id is not below 2²⁴ in size."""
    c0 = c.min(0).values
    dims = c.max(0).values - c0 + 1  # [3]
    *d, top, bottom = torch.cat([dims, fmax.max()[None], fmin.min()[None]]).tolist()  # one host read
    if d[0] * d[1] * d[2] > DENSE_CELLS or not (top < (1 << 24) and bottom > -(1 << 24)):
        return None
    idx = c - c0 + 1  # [n, 3] in a grid with one empty layer around
    flat = (idx[:, 0] * (d[1] + 2) + idx[:, 1]) * (d[2] + 2) + idx[:, 2]  # [n]
    size = (d[0] + 2) * (d[1] + 2) * (d[2] + 2)
    grid = torch.full((2, size), -(1 << 31), dtype=torch.int32, device=c.device)
    grid.scatter_reduce_(1, flat.expand(2, -1), torch.stack([fmax, -fmin]).int(), "amax")  # largest id, −smallest
    pooled = _max_around(grid.view(2, d[0] + 2, d[1] + 2, d[2] + 2))  # [2, d0, d1, d2]
    mixed = torch.zeros((d[0] + 2, d[1] + 2, d[2] + 2), dtype=torch.bool, device=c.device)
    mixed[1:-1, 1:-1, 1:-1] = pooled[0] != -pooled[1]
    return mixed.view(-1)[flat]


def _cell_coords(x: torch.Tensor, lo: torch.Tensor, size: float) -> torch.Tensor:  # [N, 3] float64 -> [N, 3] int64
    """Each point's cell of edge `size` counted from `lo`, with 3 free cells below (clamped to the keys' range)."""
    return (torch.floor((x - lo) / size).long() + 3).clamp(0, (1 << _BITS) - 4)


class _Cells:
    """Particles binned into cells of edge `size` by sorted keys (no dense grid): per occupied cell its key,
    first sorted index, count and smallest/largest fragment id. `among` [n]: bin only these particles (`order`
    then holds indices into x; `coord` still covers all; `near_foreign` needs every particle binned). `coord`
    [N, 3]: the cells `_cell_coords` gives, when already at hand."""

    def __init__(
        self,
        x: torch.Tensor,
        fragment: torch.Tensor,
        lo: torch.Tensor,
        size: float,
        among: Optional[torch.Tensor] = None,
        coord: Optional[torch.Tensor] = None,
    ):
        self.coord = _cell_coords(x, lo, size) if coord is None else coord  # [N, 3]
        self.sorted, self.order = torch.sort(_keys(self.coord if among is None else self.coord[among]))
        if among is not None:
            self.order = among[self.order]
        self.keys, self.inverse, self.count = torch.unique_consecutive(
            self.sorted, return_inverse=True, return_counts=True
        )
        self.start = torch.cumsum(self.count, 0) - self.count
        f = fragment[self.order]
        self.fmin = torch.full_like(self.keys, 1 << 40).scatter_reduce(0, self.inverse, f, "amin")
        self.fmax = torch.full_like(self.keys, -1).scatter_reduce(0, self.inverse, f, "amax")

    def find(self, keys: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(cell index, occupied) of each key."""
        i = torch.searchsorted(self.keys, keys).clamp_max(self.keys.numel() - 1)
        return i, self.keys[i] == keys

    def near_foreign(self) -> torch.Tensor:  # [N] bool
        """Particles whose cell or one of its 26 neighbours holds a particle of another fragment: the smallest and
        largest fragment id over the 27 cells differ. Over the occupied cells' bounding box, when it has at most
        DENSE_CELLS cells, by `_mixed_around`; else by 27 binary searches per occupied cell."""
        mask = (1 << _BITS) - 1
        c = torch.stack([self.keys >> (2 * _BITS), self.keys >> _BITS, self.keys], 1) & mask  # [V, 3]
        mixed = _mixed_around(c, self.fmin, self.fmax)
        if mixed is None:
            i, hit = self.find(_keys(c[:, None, :] + _cube(1, c.device)[None]))  # [V, 27]
            lo = torch.where(hit, self.fmin[i], torch.full_like(i, 1 << 40)).amin(1)
            hi = torch.where(hit, self.fmax[i], torch.full_like(i, -1)).amax(1)
            mixed = lo != hi
        out = torch.zeros(self.order.numel(), dtype=torch.bool, device=self.order.device)
        out[self.order] = mixed[self.inverse]
        return out

    def gather(
        self, coord: torch.Tensor, reach: int, other_than: Optional[torch.Tensor] = None, half: bool = False
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """(query index, particle index) for every particle in the cells within `reach` cells of each query
        cell [M, 3] (a point of the query cell sees no other particle within reach·size). `other_than` [M]: a
        fragment id per query; cells holding only that fragment's particles are left out (the pairs that remain
        come in the same order as without it). `half`: only the query's own cell and the offsets after it (the
        offsets are symmetric and sorted, the centre in the middle): one of each pair of opposite neighbours."""
        off = _cube(reach, coord.device, ball=True)
        off = off[off.shape[0] // 2 :] if half else off
        i, hit = self.find(_keys(coord[:, None, :] + off[None]))  # [M, C]
        if other_than is not None:  # a cell of the query's own piece alone holds no pair of another piece
            own = (self.fmin[i] == self.fmax[i]) & (self.fmin[i] == other_than[:, None])
            hit = hit & ~own
        i = i.reshape(-1)
        n = torch.where(hit.reshape(-1), self.count[i], torch.zeros_like(i))
        cell = torch.repeat_interleave(torch.arange(n.numel(), device=n.device), n)  # [P]
        within = torch.arange(cell.numel(), device=n.device) - (torch.cumsum(n, 0) - n)[cell]
        return torch.div(cell, off.shape[0], rounding_mode="floor"), self.order[self.start[i[cell]] + within]


def fraction_of_half_space(u: torch.Tensor) -> torch.Tensor:
    """Share of the kernel W(r) ∝ (1 − r²/R²)² inside a half-space whose face lies u·R in front of the
    kernel's centre (u > 0: the centre is inside): 1/2 + 35/32·(u − u³ + 3u⁵/5 − u⁷/7), u clamped to [−1, 1]."""
    u = u.clamp(-1.0, 1.0)
    return 0.5 + 35.0 / 32.0 * (u - u**3 + 0.6 * u**5 - u**7 / 7.0)


def depth_from_fraction(c: torch.Tensor) -> torch.Tensor:
    """u ∈ [−1, 1] with `fraction_of_half_space`(u) = c (bisection to 2⁻⁴⁰; F is monotone). The torch twin of
    `penetration_kernels.depth_from_share`, which `surface_depth` launches (one launch instead of ≈ 600 ops)."""
    c = c.clamp(0.0, 1.0)
    lo, hi = torch.full_like(c, -1.0), torch.ones_like(c)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        up = fraction_of_half_space(mid) < c
        lo, hi = torch.where(up, mid, lo), torch.where(up, hi, mid)
    return 0.5 * (lo + hi)


def kernel(u2: torch.Tensor, radius) -> torch.Tensor:
    """W = 105/(32πR³)·(1 − r²/R²)² for r < R, else 0 [1/m³] (unit integral over the ball); u2 = r²/R², radius R a
    float or a tensor broadcast with u2. `fraction_of_half_space` is the share of this kernel behind a flat face."""
    return torch.where(u2 < 1.0, 105.0 / (32.0 * math.pi * radius**3) * (1.0 - u2).clamp_min(0.0) ** 2, 0.0 * u2)


def _nearest(x: torch.Tensor, fragment: torch.Tensor, query: Optional[torch.Tensor], size: float) -> torch.Tensor:
    """Distance [m] from each query particle to its nearest other particle of the same fragment within
    `size` (inf if none): cells of edge `size`, the 27 around the query's. `query` None: every particle, each pair
    of cells visited once (the distance of a pair is the same from either end, and a minimum takes its values in
    any order)."""
    lo = x.min(0).values
    cells = _Cells(x, fragment, lo, size)
    n = x.shape[0] if query is None else query.numel()
    if query is None:  # the pairs with a neighbour cell on one side, each read for both its particles
        qi, j = cells.gather(cells.coord, 1, half=True)
        ends = (qi, j)
    else:
        qi, j = cells.gather(cells.coord[query], 1)
        ends = (qi,)
    at = qi if query is None else query[qi]  # [P] the query particle of each pair
    same = (fragment[j] == fragment[at]) & (j != at)
    d2 = torch.where(same, ((x[at] - x[j]) ** 2).sum(1), torch.full_like(x[j, 0], float("inf")))
    nearest = torch.full((n,), float("inf"), dtype=x.dtype, device=x.device)
    for end in ends:
        nearest = nearest.scatter_reduce(0, end, d2, "amin")
    return nearest.sqrt()


def _sampled(fragment: torch.Tensor, K: int, samples: int) -> torch.Tensor:
    """Up to `samples` particle indices per fragment id, drawn in a fixed random order (a stride through the
    index order could pick one lattice layer of a block made by a meshgrid)."""
    g = torch.Generator().manual_seed(0)
    perm = torch.randperm(fragment.numel(), generator=g).to(fragment.device)
    order = perm[torch.argsort(fragment[perm], stable=True)]  # by fragment, random within each
    count = torch.bincount(fragment, minlength=K)
    start = torch.cumsum(count, 0) - count
    rank = torch.arange(order.numel(), device=fragment.device) - start[fragment[order]]
    return order[rank < samples]


def _group_median(values: torch.Tensor, groups: torch.Tensor, K: int) -> tuple[torch.Tensor, torch.Tensor]:
    """(median [K] of `values` per group id in 0..K−1 (lower middle), count [K]); 0 where a group is empty."""
    order = torch.argsort(values)
    order = order[torch.argsort(groups[order], stable=True)]  # by group, ascending values within
    count = torch.bincount(groups, minlength=K)
    start = torch.cumsum(count, 0) - count
    mid = (start + torch.div(count - 1, 2, rounding_mode="floor")).clamp(0, max(values.numel() - 1, 0))
    med = values[order][mid] if values.numel() else torch.zeros(K, dtype=values.dtype, device=values.device)
    return torch.where(count > 0, med, torch.zeros_like(med)), count


def _adds_something(inside: torch.Tensor, scaled: torch.Tensor, odd: Optional[torch.Tensor]) -> torch.Tensor:
    """[P] bool: the pairs whose kernel term W·J (and its products with the offset) may differ from ±0: those `inside`
    the ball, and any whose squared distance over the radius² (`scaled`, non-finite when an offset is) or weight J is
    not finite (`odd`, None when no weight is; 0·inf and 0·NaN are NaN). Leaving the others out of a sum that starts
    at +0 changes none of its bits: a float sum from +0 never reads −0, and s + ±0 = s."""
    out = inside | ~torch.isfinite(scaled)
    return out if odd is None else out | odd


def calibrate(
    x: torch.Tensor, fragment: torch.Tensor, volume_ratio: Optional[torch.Tensor] = None, samples: int = SAMPLES
) -> dict:
    """The measure's scales, from the particles' positions alone (stored volumes are not trusted: in the
    built-in scenes they sum to ≈ 2× the solid and spread 50×).

    radius R = SPACINGS · s, the spacing s = median nearest-neighbour distance / NN_PER_SPACING. filled [K]:
    per fragment id, the unit-weight kernel sum Σ_j W(|x − x_j|) [1/m³] of a ball the piece fills, i.e. its
    number density: the median sum at its own particles whose kernel-weighted neighbours are centred on them
    (|centroid offset| < CENTRED·R: a ball no face cuts; up to `samples` tried per piece), and at least the
    density its spacing implies, (NN_PER_SPACING / its median nearest-neighbour distance)³ — all a piece
    too small or thin to fill a ball gets. `volume_ratio` [N]: each particle's current volume over its rest
    volume (det F), the sums' weights, so a piece compressed at an impact keeps its rest density (default 1).
    Returns {"radius": R [m], "filled": [K] float64 (1 for an empty id), "spacing": s [m]}."""
    ok = fragment >= 0
    K = int(fragment.max()) + 1 if bool(ok.any()) else 0
    out = {"radius": 0.0, "filled": torch.ones(max(K, 1), dtype=torch.float64, device=x.device), "spacing": 0.0}
    if K == 0:
        return out
    idx = torch.nonzero(ok).flatten()
    xd, frag = x.double()[idx], fragment.long()[idx]
    J = torch.ones_like(xd[:, 0]) if volume_ratio is None else volume_ratio.double()[idx]  # [N'] weights
    box = (xd.max(0).values - xd.min(0).values).clamp_min(1e-12)
    guess = float(box.prod() / idx.numel()) ** (1.0 / 3.0)  # ≥ the spacing: the box holds the solid
    nn = _nearest(xd, frag, None, guess)  # [N']
    finite = torch.isfinite(nn)
    if not bool(finite.any()):
        return out
    spacing = float(nn[finite].median()) / NN_PER_SPACING
    R = SPACINGS * spacing
    gap, _ = _group_median(torch.where(finite, nn, torch.full_like(nn, spacing * NN_PER_SPACING)), frag, K)
    pick = _sampled(frag, K, samples)  # [S] sampled particles, per fragment
    cells = _Cells(xd, frag, xd.min(0).values, R / 3)
    qi, j = cells.gather(cells.coord[pick], 3)
    d = xd[j] - xd[pick][qi]  # [P, 3]
    d2, Jj = (d**2).sum(1), J[j]  # [P]
    u2 = d2 / (R * R)
    keep = (frag[j] == frag[pick][qi]) & (u2 < 1.0)
    # a pair outside the ball adds a zero (±0: a sum from +0 keeps its bits) unless a non-finite weight or offset
    # makes it NaN; the others are summed in their order
    odd = None if bool(torch.isfinite(J).all()) else ~torch.isfinite(Jj)  # [P] pairs of a non-finite weight
    a = torch.nonzero(_adds_something(keep, u2, odd)).flatten()
    w = torch.where(keep[a], kernel(u2[a], R), torch.zeros_like(u2[a])) * Jj[a]
    own = torch.zeros(pick.numel(), dtype=torch.float64, device=x.device).index_add_(0, qi[a], w)  # [S]
    moment = torch.zeros(pick.numel(), 3, dtype=torch.float64, device=x.device).index_add_(0, qi[a], w[:, None] * d[a])
    centred = moment.norm(dim=1) < CENTRED * R * own  # [S] the neighbours' centroid within CENTRED·R
    fp = frag[pick]
    inner, n_inner = _group_median(own[centred], fp[centred], K)
    # the density any sampler gives, from a small ball (DENSITY_REACH nearest-neighbour distances) that fits
    # inside thin and small pieces, counting every fragment's particles (at a latch the pieces just cut are one
    # body, so a thin layer cut from its twin still fills the ball): its sums where no free face cuts the ball
    r = DENSITY_REACH * gap[fp][qi]  # [P] per pair, the query's piece's small radius
    v2 = d2 / (r * r)
    b = torch.nonzero(_adds_something(v2 < 1.0, v2, odd)).flatten()  # as above: the pairs that add a non-zero
    qb, db = qi[b], d[b]
    ws = kernel(v2[b], r[b]) * Jj[b]
    small = torch.zeros(pick.numel(), dtype=torch.float64, device=x.device).index_add_(0, qb, ws)  # [S]
    ms = torch.zeros(pick.numel(), 3, dtype=torch.float64, device=x.device).index_add_(0, qb, ws[:, None] * db)
    cov = torch.zeros(pick.numel(), 3, 3, dtype=torch.float64, device=x.device).index_add_(
        0, qb, ws[:, None, None] * db[:, :, None] * db[:, None, :]
    )  # [S, 3, 3] the neighbours' second moment: a ball cut on two sides (a thin plate's) is flat, not round
    eig = torch.linalg.eigvalsh(cov)  # [S, 3] ascending
    round_ = eig[:, 0] > ISOTROPY * eig[:, 2]
    full = (ms.norm(dim=1) < SMALL_CENTRED * DENSITY_REACH * gap[fp] * small) & round_  # [S]
    dens, n_dens = _group_median(small[full] * gap[fp[full]] ** 3, fp[full], K)  # density × gap³ per piece
    typical = float((small[full] * gap[fp[full]] ** 3).median()) if bool(full.any()) else NN_PER_SPACING**3
    implied = torch.where(n_dens > 0, dens, torch.full_like(dens, typical)) / gap.clamp_min(1e-30) ** 3
    filled = torch.where(n_inner > 0, torch.maximum(inner, SMALL_TRUST * implied), SMALL_TRUST * implied)
    present = torch.bincount(frag, minlength=K) > 0
    out.update(radius=R, spacing=spacing, filled=torch.where(present, filled, torch.ones_like(filled)))
    return out


def _volume_ratio_now(volume_ratio):  # tensor, zero-argument function or None -> [N] tensor or None
    return volume_ratio() if callable(volume_ratio) else volume_ratio


def surface_depth(
    x: torch.Tensor,
    fragment: torch.Tensor,
    calibration: dict,
    volume_ratio: Union[torch.Tensor, Callable[[], torch.Tensor], None] = None,
    chunk: int = CHUNK,
    twin: bool = False,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Per particle, the deepest depth [m] behind another fragment's surface and that fragment's id.

    x [N, 3], fragment [N] (−1: unlabelled, ignored), calibration from `calibrate` (radius R, each fragment's
    filled density; ids beyond it are not evaluated). Returns (depth [N] float64, 0 where no particle lies behind
    another piece's surface or none was evaluated; into [N] int64, −1 there). A depth saturates at R.
    `volume_ratio` [N]: det F per particle, its weight (as in `calibrate`; default 1), or a function that returns it,
    called only when some particle lies near another piece (most frames have none). The sums and depths run in
    Warp (`penetration_kernels`); `twin` runs the torch twin instead (`behind_surfaces_torch`, `chunk` queries at a
    time), for tests."""
    radius, filled = float(calibration["radius"]), calibration["filled"].to(x.device, torch.float64)
    n = x.shape[0]
    depth = torch.zeros(n, dtype=torch.float64, device=x.device)
    into = torch.full((n,), -1, dtype=torch.long, device=x.device)
    ok = fragment >= 0
    if n == 0 or radius <= 0 or not bool(ok.any()):
        return depth, into
    ok = ok & (fragment < filled.numel())
    frag = torch.where(ok, fragment.long(), torch.full_like(fragment, -1, dtype=torch.long))
    xd = x.double()
    every = x.device.type == "cpu" and bool(ok.all())  # every particle labelled (a free host read on the CPU only)
    lo = (xd if every else torch.where(ok[:, None], xd, torch.full_like(xd, float("inf")))).min(0).values
    spacing = radius / SPACINGS
    coord = _cell_coords(xd, lo, NEAR * spacing)  # [N, 3]
    near = _mixed_around(coord, frag, frag)  # frag ≥ −1: the bounds `_Cells` starts its extremes from change nothing
    near = _Cells(xd, frag, lo, NEAR * spacing, coord=coord).near_foreign() if near is None else near
    query = torch.nonzero(near & ok).flatten()  # [M0] particles in cells by another fragment
    if query.numel() == 0:
        return depth, into
    # a particle of another piece within a cell of a query is itself in cells by another fragment (the query's): the
    # cells hold only those
    small = _Cells(xd, frag, lo, NEAR * spacing, among=torch.nonzero(near).flatten(), coord=coord)
    # a particle behind b's surface has a particle of b within about a spacing (b's sample is dense there)
    if twin:
        qi, j = small.gather(small.coord[query], 1)
        gap2 = ((xd[query][qi] - xd[j]) ** 2).sum(1)
        close = (frag[j] != frag[query][qi]) & (frag[j] >= 0) & (gap2 < (NEAR * spacing) ** 2)
        query = query[torch.zeros(query.numel(), dtype=torch.bool, device=x.device).index_fill_(0, qi[close], True)]
    else:
        query = query[near_another_piece_mask(xd, frag, small, query, NEAR * spacing, _BITS)]
    if query.numel() == 0:
        return depth, into
    big = _Cells(xd, frag, lo, radius / 3)  # cells within 3 of the query's: every particle within R
    volume_ratio = _volume_ratio_now(volume_ratio)
    J = torch.ones_like(xd[:, 0]) if volume_ratio is None else volume_ratio.double()  # [N] weights
    if twin:
        best, which = behind_surfaces_torch(xd, lo, frag, J, filled, radius, big, query, chunk)
    else:
        rows = max(1, DENSE_LIMIT // filled.numel())  # queries whose [rows, K] sums are held at once
        offsets = _cube(3, x.device, ball=True)  # the cells whose points can lie within R of the query cell's
        best, which = deepest_behind_surfaces(xd, frag, J, filled, radius, big, offsets, query, _BITS, rows)
    depth[query], into[query] = best, which
    return depth, into


def behind_surfaces_torch(
    xd: torch.Tensor,
    lo: torch.Tensor,
    frag: torch.Tensor,
    J: torch.Tensor,
    filled: torch.Tensor,
    radius: float,
    big: _Cells,
    query: torch.Tensor,
    chunk: int = CHUNK,
) -> tuple[torch.Tensor, torch.Tensor]:
    """The torch twin of `penetration_kernels.deepest_behind_surfaces`: (depth [M] float64 [m], into [M] int64) of
    each query particle behind the other pieces' surfaces, from every (query, particle) pair of the cells around it
    (pair offsets in float32), `chunk` queries at a time."""
    K, n = filled.numel(), query.numel()
    depth = torch.zeros(n, dtype=torch.float64, device=xd.device)
    into = torch.full((n,), -1, dtype=torch.long, device=xd.device)
    xf = (xd - lo).float()  # pair offsets in float32 (relative to the box: ample for |x_p − x_j| ≤ R)
    for s in range(0, n, chunk):
        q = query[s : s + chunk]
        qi, j = big.gather(big.coord[q], 3, other_than=frag[q])  # pairs with another piece's particles only
        fq, fj = frag[q][qi], frag[j]
        u2 = ((xf[q][qi] - xf[j]) ** 2).sum(1) / (radius * radius)
        keep = (fj >= 0) & (fj != fq) & (u2 < 1.0)
        qi, fj = qi[keep], fj[keep]
        w = kernel(u2[keep].double(), radius) / filled[fj] * J[j[keep]]  # each particle 1/n_b of b's volume, × det F
        m = q.numel()
        if m * K <= DENSE_LIMIT:
            frac = torch.zeros(m * K, dtype=torch.float64, device=xd.device).index_add_(0, qi * K + fj, w)
            key = torch.nonzero(frac > 0.5).flatten()  # behind b's surface only where b fills over half
            frac = frac[key]
        else:
            key, inv = torch.unique(qi * K + fj, return_inverse=True)
            frac = torch.zeros(key.numel(), dtype=torch.float64, device=xd.device).index_add_(0, inv, w)
            key, frac = key[frac > 0.5], frac[frac > 0.5]
        d = radius * depth_from_fraction(frac)  # [E] entries (candidate, other fragment)
        row, other = torch.div(key, K, rounding_mode="floor"), key % K
        best = torch.zeros(m, dtype=torch.float64, device=xd.device).scatter_reduce(0, row, d, "amax")
        hit = (best[row] == d) & (d > 0)
        which = torch.full((m,), -1, dtype=torch.long, device=xd.device).scatter_reduce(0, row[hit], other[hit], "amax")
        depth[s : s + chunk], into[s : s + chunk] = best, which
    return depth, into


DENSE_PAIRS = 32  # `surface_penetration` sums up on a dense K × K table, read in one transfer, up to this many ids


def _summary_dense(depth, fragment, into, crossing_at: float, K: int, out: dict, rows: Optional[int] = None) -> dict:
    """`surface_penetration`'s summary of (depth, into) [N] from a dense [K·K] table of each ordered pair's deepest
    depth, the crossing count beside it, in one host read (the sorted-keys summary reads the device eight times).
    The same numbers: a particle behind a surface has depth > 0 (`surface_depth`), so the table's non-zero entries
    are the pairs present, the largest of the maxima is the deepest, and the pairs come in (a, b) order. `rows`:
    partial tables the maxima are spread over (particle index mod rows), default 256 on CUDA (atomics on a few
    addresses queue up: 143 µs a frame at 183k particles with one table) and 1 elsewhere; any number gives the same."""
    hit = into >= 0  # [N]
    rows = rows or (256 if depth.is_cuda else 1)
    row = torch.arange(depth.numel(), device=depth.device) % rows
    key = row * (K * K + 1) + torch.where(hit, fragment.long() * K + into, torch.full_like(into, K * K))  # K²: none
    worst = torch.zeros(rows * (K * K + 1), dtype=torch.float64, device=depth.device)
    worst = worst.scatter_reduce_(0, key, depth, "amax").view(rows, K * K + 1)[:, : K * K].amax(0)
    crossing = (hit & (depth > crossing_at)).sum()
    *table, count = torch.cat([worst, crossing.double()[None]]).tolist()  # the one host read
    pairs = {(k // K, k % K): v for k, v in enumerate(table) if v > 0}
    if pairs:
        out.update(depth=max(pairs.values()), crossing=int(count), pairs=pairs)
    return out


def surface_penetration(
    x: torch.Tensor,
    fragment: torch.Tensor,
    crossing_at: float,
    calibration: Optional[dict] = None,
    volume_ratio: Union[torch.Tensor, Callable[[], torch.Tensor], None] = None,
) -> dict:
    """`surface_depth` summed up: {"depth": deepest [m] (0 if none), "crossing": particles deeper than
    `crossing_at` [m], "pairs": {(a, b): deepest depth [m] of a behind b's surface}, "radius": R [m]}.
    `calibration`: from `calibrate` at the latch, while no piece overlaps another (pieces overlapping then
    count their overlap as density); made from `x` now if None or short of a fragment id.
    `volume_ratio` [N]: det F per particle (see `calibrate`), or a function that returns it (`surface_depth`)."""
    K = int(fragment.max()) + 1 if fragment.numel() else 0
    if calibration is None or calibration["filled"].numel() < K:
        volume_ratio = _volume_ratio_now(volume_ratio)
        calibration = calibrate(x, fragment, volume_ratio)
    depth, into = surface_depth(x, fragment, calibration, volume_ratio)
    out = {"depth": 0.0, "crossing": 0, "pairs": {}, "radius": float(calibration["radius"])}
    K = calibration["filled"].numel()  # ids of both ends are below it (`surface_depth` evaluates no other)
    if K <= DENSE_PAIRS:
        return _summary_dense(depth, fragment, into, crossing_at, K, out)
    inside = torch.nonzero(into >= 0).flatten()
    if inside.numel() == 0:
        return out
    d, a, b = depth[inside], fragment[inside].long(), into[inside]
    K = int(max(int(a.max()), int(b.max()))) + 1
    keys, inv = torch.unique(a * K + b, return_inverse=True)
    worst = torch.zeros(keys.numel(), dtype=torch.float64, device=x.device).scatter_reduce(0, inv, d, "amax")
    out["depth"] = float(d.max())
    out["crossing"] = int((d > crossing_at).sum())
    out["pairs"] = {(int(k) // K, int(k) % K): float(v) for k, v in zip(keys.tolist(), worst.tolist())}
    return out
