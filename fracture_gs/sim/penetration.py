"""Fragment-aware penetration, measured between the pieces themselves (DESIGN.md "Many fragments").

The paper's columns measure crossing along the latched normal n_Π, which misreads a piece that
tumbles (Table 4, Panel A). Here space is cut into voxels of edge h ≈ 0.6 Δx (a little over the
particle spacing); each voxel belongs to the fragment that has most particles in it, and a
fragment's *occupied volume* is its voxels eroded once (a voxel counts when its six face
neighbours belong to the same fragment), so the ragged surface layer, where touching pieces and
oblique cuts interleave, is excluded. A particle of fragment a inside b's occupied volume is an
identity crossing; its depth is the number of erosions its voxel survives, times h (a lower bound
on how far it is inside b). Vectorised torch on the particles' device (sorted keys and binary
searches, no dense grid).
"""

from __future__ import annotations

import torch

_NEIGHBOURS = ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1))


def _member(sorted_keys: torch.Tensor, query: torch.Tensor) -> torch.Tensor:
    """query ∈ sorted_keys, elementwise (binary search)."""
    if sorted_keys.numel() == 0:
        return torch.zeros_like(query, dtype=torch.bool)
    i = torch.searchsorted(sorted_keys, query).clamp_max(sorted_keys.numel() - 1)
    return sorted_keys[i] == query


def fragment_overlap(x: torch.Tensor, fragment: torch.Tensor, h: float, max_depth: int = 8) -> dict:
    """Particles of one fragment inside another's occupied volume.

    x [N,3], fragment [N] (ids ≥ 0). Returns {"crossing": count, "depth": max depth [m] (0 if none),
    "pairs": {(a, b): max depth [m]} for fragment a inside b}."""
    ok = fragment >= 0
    if int(ok.sum()) == 0 or int(fragment.max()) < 1:
        return {"crossing": 0, "depth": 0.0, "pairs": {}}
    x, frag = x[ok].double(), fragment[ok].long()
    K = int(frag.max()) + 1
    cell = torch.floor((x - x.min(0).values) / h).long() + 1  # a free layer of voxels around
    dims = cell.max(0).values + 2
    stride = torch.stack([dims[1] * dims[2], dims[2], torch.ones_like(dims[2])])
    vox = (cell * stride).sum(1)  # [N]
    pairs, counts = torch.unique(vox * K + frag, return_counts=True)  # sorted (voxel, fragment) keys
    vox_of = pairs // K
    voxels, inverse = torch.unique_consecutive(vox_of, return_inverse=True)
    best = torch.zeros(voxels.numel(), dtype=counts.dtype, device=x.device).scatter_reduce(0, inverse, counts, "amax")
    top = counts == best[inverse]
    # the owner of each voxel: its most numerous fragment (ties: the lowest id, the first key of the run)
    winner = torch.zeros(voxels.numel(), dtype=torch.long, device=x.device).scatter_reduce(
        0, inverse[top], torch.arange(pairs.numel(), device=x.device)[top], "amin", include_self=False
    )
    occ = pairs[winner]  # one (voxel, owner) key per voxel, sorted
    level = torch.zeros(occ.numel(), dtype=torch.long, device=x.device)
    alive = torch.arange(occ.numel(), device=x.device)
    current = occ
    steps = [int((torch.tensor(d, device=x.device) * stride).sum()) * K for d in _NEIGHBOURS]
    for _ in range(max_depth):
        keep = torch.ones(current.numel(), dtype=torch.bool, device=x.device)
        for s in steps:
            keep &= _member(current, current + s)
        alive, current = alive[keep], current[keep]
        if current.numel() == 0:
            break
        level[alive] += 1
    inner = level > 0
    ikey, ilevel = occ[inner], level[inner]
    if ikey.numel() == 0:
        return {"crossing": 0, "depth": 0.0, "pairs": {}}
    ivox, ifrag = ikey // K, ikey % K
    order = torch.argsort(vox)
    svox = vox[order]
    start = torch.searchsorted(svox, ivox)
    count = torch.searchsorted(svox, ivox, right=True) - start
    rep = torch.repeat_interleave(torch.arange(ikey.numel(), device=x.device), count)
    if rep.numel() == 0:
        return {"crossing": 0, "depth": 0.0, "pairs": {}}
    offset = torch.arange(rep.numel(), device=x.device) - torch.repeat_interleave(torch.cumsum(count, 0) - count, count)
    p = order[start[rep] + offset]  # particles sitting in an inner voxel of fragment ifrag[rep]
    foreign = frag[p] != ifrag[rep]
    p, host, depth = p[foreign], ifrag[rep][foreign], ilevel[rep][foreign].double() * h
    if p.numel() == 0:
        return {"crossing": 0, "depth": 0.0, "pairs": {}}
    pair = frag[p] * K + host
    worst = torch.zeros(K * K, dtype=torch.float64, device=x.device).scatter_reduce(0, pair, depth, "amax")
    hits = torch.nonzero(worst > 0).flatten().tolist()
    values = worst[hits].tolist()
    return {
        "crossing": int(torch.unique(p).numel()),
        "depth": float(depth.max()),
        "pairs": {(k // K, k % K): v for k, v in zip(hits, values)},
    }


def collider_crossing(x: torch.Tensor, planes, tolerance: float) -> tuple[int, float]:
    """(particles behind a plane collider by more than `tolerance` [m], deepest such distance [m])."""
    count, depth = 0, 0.0
    xd = x.double()
    for b in planes:
        n = torch.tensor(b.normal, dtype=torch.float64, device=x.device)
        d = (xd - torch.tensor(b.point, dtype=torch.float64, device=x.device)) @ (n / n.norm())
        below = d < -tolerance
        count += int(below.sum())
        if bool(below.any()):
            depth = max(depth, float(-d[below].min()))
    return count, depth
