"""The grid's extent: the nodes a config asks for (explicit, or fitted to the particles), checked before anything is
allocated: the particles inside, the node count under `sim.max_grid_cells`, the buffers in a GPU's free memory."""

from __future__ import annotations

import math

import torch

from ...config import SimConfig
from ...errors import SimulationError


def fit_grid(cfg: SimConfig, x: torch.Tensor) -> tuple[tuple, float, tuple]:
    """(origin, dx, shape) for the config: explicit, or fitted to the particles' bounds plus
    `grid_margin` of their extent and the wall cells (and `grid_bounds` if given). The origin is
    rounded down to a multiple of Δx so nodes sit at integer multiples of Δx."""
    dx = float(cfg.dx)
    if cfg.grid == "explicit":
        origin = tuple(math.floor(o / dx + 1e-6) * dx for o in cfg.grid_origin)
        shape = tuple(int(s) for s in cfg.grid_shape)
        check_grid_size(shape, dx, cfg.max_grid_cells, "sim.grid_shape")
        return origin, dx, shape
    if cfg.grid != "auto":
        raise SimulationError(f"sim.grid must be 'explicit' or 'auto', not '{cfg.grid}'")
    lo = x.min(dim=0).values.double().cpu()
    hi = x.max(dim=0).values.double().cpu()
    pad = (hi - lo) * cfg.grid_margin + (cfg.wall_cells + 2) * dx
    lo, hi = lo - pad, hi + pad
    if cfg.grid_bounds is not None:
        lo = torch.minimum(lo, torch.tensor(cfg.grid_bounds[0], dtype=torch.float64) - (cfg.wall_cells + 2) * dx)
        hi = torch.maximum(hi, torch.tensor(cfg.grid_bounds[1], dtype=torch.float64) + (cfg.wall_cells + 2) * dx)
    if not bool(torch.isfinite(lo).all() and torch.isfinite(hi).all()):
        raise SimulationError('sim.grid = "auto": the particles\' bounds are not finite; remove NaN or inf positions')
    origin = tuple(math.floor(float(a) / dx) * dx for a in lo)
    shape = tuple(int(math.ceil((float(b) - o) / dx)) + 1 for o, b in zip(origin, hi))
    check_grid_size(shape, dx, cfg.max_grid_cells, "an automatic grid fitted to the particles")
    return origin, dx, shape


def check_inside(x: torch.Tensor, origin, dx: float, shape) -> None:  # x [N, 3]
    """One sentence when particles start outside the grid's nodes (an explicit grid that misses them)."""
    lo = torch.tensor(origin, dtype=torch.float64, device=x.device)
    hi = lo + (torch.tensor(shape, dtype=torch.float64, device=x.device) - 1) * dx
    xd = x.detach().double()
    outside = ((xd < lo) | (xd > hi)).any(dim=1)
    n_out = int(outside.sum())
    if n_out:
        first = xd[outside][0].tolist()
        raise SimulationError(
            f"{n_out} of {len(x)} particles start outside the grid [{', '.join(f'{v:g}' for v in lo.tolist())}] to "
            f"[{', '.join(f'{v:g}' for v in hi.tolist())}] m (first at {[round(v, 4) for v in first]}); move the "
            'grid (sim.grid_origin, sim.grid_shape) over them or use sim.grid = "auto"'
        )


BYTES_PER_NODE = 32  # dense slot 0: (p, m) 16 B + velocity 12 B + owner word 4 B


def check_grid_size(shape, dx: float, cap: int, what: str) -> None:
    """One sentence, before anything is allocated, when a grid would exceed `sim.max_grid_cells` nodes."""
    nodes = 1
    for s in shape:
        nodes *= int(s)
    if nodes > cap:
        dims = "×".join(str(int(s)) if s < 1e9 else f"{float(s):.3g}" for s in shape)
        count = f"{nodes:,}" if nodes < 1e15 else f"{float(nodes):.3g}"
        raise SimulationError(
            f"{what} would be {dims} = {count} nodes (≈ {nodes * BYTES_PER_NODE / 2**30:.3g} GiB at Δx = {dx:g} m), "
            f"over sim.max_grid_cells = {cap:,}; remove far-away particles (floaters), lower sim.grid_margin, "
            f"raise sim.dx, or raise sim.max_grid_cells if the memory is there"
        )


def check_device_memory(need: int, device: str, shape) -> None:
    """One sentence before allocating when a CUDA device lacks the free memory for the grid buffers."""
    if not str(device).startswith("cuda"):
        return
    free, _ = torch.cuda.mem_get_info(torch.device(device))
    if need > 0.9 * free:
        raise SimulationError(
            f"a {'×'.join(map(str, shape))} grid needs ≈ {need / 2**30:.2f} GiB but {device} has "
            f"{free / 2**30:.2f} GiB free; use a coarser grid (raise sim.dx) or free the GPU"
        )
