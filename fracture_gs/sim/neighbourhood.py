"""Torch-side particle queries of the solver: memory order for P2G's atomics, which particles no
other fragment can reach this frame ("solo"), and fragment mass centroids. Pure torch, on the
particles' device; no Warp."""

from __future__ import annotations

import math

import torch

from ..errors import SimulationError
from ..runtime import device_constant


def cell_order(x: torch.Tensor, origin, dx: float, shape, mode: str = "interleaved", fragment=None) -> torch.Tensor:
    """Permutation of particles (new i = old order[i]) for P2G's atomics.

    `cell`: order of the stencil's base node ⌊ξ − 0.5⌋ (the cells of the grid shifted by half a cell):
    consecutive particles share all 27 nodes, which `grid.run_kernels.p2g_runs` sums before the atomics (in
    one warp they would otherwise add to the same nodes at once). `interleaved`: the k-th
    particle of every cell, in cell order, then the (k+1)-th, ... — neighbours in memory are
    neighbouring cells, so a warp keeps locality while few of its lanes add to the same node. `fragment` ([N],
    after a latch): within a cell, by fragment, so a run of one cell's particles breaks at most once per
    fragment present there (P2G into per-fragment fields)."""
    if mode not in ("cell", "interleaved"):
        raise SimulationError(f"sort mode '{mode}' is not 'cell' or 'interleaved'")
    shift = 0.5 if mode == "cell" else 0.0
    cell = torch.floor((x - device_constant(origin, torch.float32, x.device)) / dx - shift).long()  # [N, 3]
    key = (cell[:, 0] * shape[1] + cell[:, 1]) * shape[2] + cell[:, 2]  # [N]
    if fragment is not None and fragment.numel():
        f = fragment.long().clamp_min(0)
        key = key * (int(f.max()) + 1) + f
    order = torch.argsort(key, stable=True)
    if mode == "interleaved" and len(order):
        sorted_key = key[order] - key[order[0]]  # from 0: particles below the origin have negative keys
        _, counts = torch.unique_consecutive(sorted_key, return_counts=True)
        starts = torch.repeat_interleave(torch.cumsum(counts, 0) - counts, counts)
        rank = torch.arange(len(order), device=key.device) - starts
        order = order[torch.argsort(rank * (int(sorted_key[-1]) + 1) + sorted_key, stable=True)]
    return order


def solo_radius(reach: float, dx: float) -> int | None:
    """The neighbourhood of `solo_mask` in cells of 2Δx, or None past 6 cells (nobody is solo)."""
    r = math.ceil(reach / (2.0 * dx))
    return None if r > 6 else r


def solo_mask(x: torch.Tensor, fragment: torch.Tensor, origin, dx: float, shape, reach: float) -> torch.Tensor | None:
    """1 for particles with no particle of another fragment within `reach` metres, else 0 ([N] int32).

    Conservative: cells of 2Δx, fragment id min and max pooled over ⌈reach / 2Δx⌉ cells. None when
    the reach spans more than 6 such cells (fast or escaping particles: nobody is solo)."""
    h = 2.0 * dx
    r = solo_radius(reach, dx)
    if r is None:
        return None
    dims = [int(math.ceil(s * dx / h)) + 1 for s in shape]
    cell = torch.floor((x - device_constant(origin, torch.float32, x.device)) / h).long()  # [N, 3]
    cell = torch.minimum(cell.clamp_min(0), device_constant(dims, torch.int64, x.device) - 1)
    lin = (cell[:, 0] * dims[1] + cell[:, 1]) * dims[2] + cell[:, 2]  # [N]
    frag = fragment.float()
    inf = torch.full((dims[0] * dims[1] * dims[2],), float("inf"), device=x.device)
    lo = inf.scatter_reduce(0, lin, frag, "amin").view(1, 1, *dims)
    hi = (-inf).scatter_reduce(0, lin, frag, "amax").view(1, 1, *dims)
    lo = -_cube_max(-lo, r).flatten()
    hi = _cube_max(hi, r).flatten()
    return (lo[lin] == hi[lin]).to(torch.int32)


def _cube_max(t: torch.Tensor, r: int) -> torch.Tensor:  # [1, 1, X, Y, Z] -> same
    """Max over the (2r + 1)³ cube around every cell as three 1-D passes (max is separable: the same
    values as one 3-D pool, with 3(2r + 1) instead of (2r + 1)³ reads per cell)."""
    pool = torch.nn.functional.max_pool3d
    k = 2 * r + 1
    t = pool(t, (k, 1, 1), stride=1, padding=(r, 0, 0))
    t = pool(t, (1, k, 1), stride=1, padding=(0, r, 0))
    return pool(t, (1, 1, k), stride=1, padding=(0, 0, r))


def fragment_centroids(x: torch.Tensor, mass: torch.Tensor, fragment: torch.Tensor, count: int) -> torch.Tensor:
    """Mass centroid of each of `count` fragments ([count, 3]; zero for an empty fragment)."""
    k = fragment.long().clamp(0, count - 1)
    mx = torch.zeros(count, 3, dtype=torch.float32, device=x.device)
    m = torch.zeros(count, dtype=torch.float32, device=x.device)
    mx.index_add_(0, k, mass[:, None] * x)
    m.index_add_(0, k, mass)
    return mx / m.clamp_min(1e-30)[:, None]
