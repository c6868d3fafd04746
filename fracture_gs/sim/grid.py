"""`Grid`: dense nodal fields m^k, p^k, v^k, m^k_band (k = 0, or k ∈ {0, 1} after a multi-field latch)."""
from __future__ import annotations

import math

import torch
import warp as wp

from ..config import SimConfig
from .transfer import N_STATS, NEVER, STAT_FIRST_T


def fit_grid(cfg: SimConfig, x: torch.Tensor) -> tuple[tuple, float, tuple]:
    """(origin, dx, shape) for the config: explicit, or fitted to the particles' bounds plus
    `grid_margin` of their extent and the wall cells (and `grid_bounds` if given). The origin is
    rounded down to a multiple of Δx so nodes sit at integer multiples of Δx."""
    dx = float(cfg.dx)
    if cfg.grid == "explicit":
        origin = tuple(math.floor(o / dx + 1e-6) * dx for o in cfg.grid_origin)
        return origin, dx, tuple(int(s) for s in cfg.grid_shape)
    if cfg.grid != "auto":
        raise ValueError(f"sim.grid must be 'explicit' or 'auto', not '{cfg.grid}'")
    lo = x.min(dim=0).values.double().cpu()
    hi = x.max(dim=0).values.double().cpu()
    pad = (hi - lo) * cfg.grid_margin + (cfg.wall_cells + 2) * dx
    lo, hi = lo - pad, hi + pad
    if cfg.grid_bounds is not None:
        lo = torch.minimum(lo, torch.tensor(cfg.grid_bounds[0], dtype=torch.float64) - (cfg.wall_cells + 2) * dx)
        hi = torch.maximum(hi, torch.tensor(cfg.grid_bounds[1], dtype=torch.float64) + (cfg.wall_cells + 2) * dx)
    origin = tuple(math.floor(float(a) / dx) * dx for a in lo)
    shape = tuple(int(math.ceil((float(b) - o) / dx)) + 1 for o, b in zip(origin, hi))
    return origin, dx, shape


class Grid:
    """Dense per-field node buffers as torch tensors with Warp views made once.

    `mass[k]`, `momentum[k]`, `velocity[k]`, `band_mass[k]` are field k at every node; the second
    field is allocated only for the fragment-conditioned variants."""

    def __init__(self, origin, dx: float, shape, n_fields: int, device: str):
        self.origin = tuple(float(o) for o in origin)
        self.dx = float(dx)
        self.shape = tuple(int(s) for s in shape)
        if min(self.shape) < 5:
            raise ValueError(f"sim.grid_shape {self.shape} is too small; every axis needs at least 5 nodes")
        self.n_fields = n_fields
        full = (n_fields, *self.shape)
        # (p^k, m^k) packed per node so P2G scatters both with one 16-byte atomic; mass and
        # momentum are views into it
        self.mp = torch.zeros((*full, 4), dtype=torch.float32, device=device)
        self.mass = self.mp[..., 3]
        self.momentum = self.mp[..., :3]
        self.velocity = torch.zeros((*full, 3), dtype=torch.float32, device=device)
        self.band_mass = torch.zeros(full, dtype=torch.float32, device=device)
        self.contact_stats = torch.zeros(N_STATS, dtype=torch.float32, device=device)
        self.contact_stats[STAT_FIRST_T] = NEVER
        self.wp = dict(
            mp=wp.from_torch(self.mp, dtype=wp.vec4),
            velocity=wp.from_torch(self.velocity, dtype=wp.vec3),
            band_mass=wp.from_torch(self.band_mass),
            stats=wp.from_torch(self.contact_stats),
        )

    def clear(self, n_fields: int | None = None, band: bool = True):
        """Reset the accumulators of the first `n_fields` fields (no allocation)."""
        self.mp[:n_fields].zero_()
        if band:
            self.band_mass[:n_fields].zero_()

    @property
    def nbytes(self) -> int:
        """Grid-buffer footprint (mass, momentum, velocity, band mass) in bytes."""
        return sum(t.numel() * t.element_size() for t in (self.mp, self.velocity, self.band_mass))
