"""`Grid`: nodal fields m^k, p^k, v^k, m^k_band (k = 0, or k ∈ {0, 1} after a multi-field latch).

Storage follows "second fields only where fragments share support" (DESIGN.md, Performance
rules). Slot 0 is dense over the grid. Fragment 1's field lives in slot 1 only on the shared box
S = B⁰ ∩ B¹ of the two fields' boxes (each fragment's particles plus stencil and travel). Outside
S at most one fragment can reach a node, so its field sits in slot 0 there, with the same
normalization, gravity and boundaries; contact and band mass matter only inside S. The logical
fields `mass`, `momentum`, `velocity` and `band_mass` ([K, X, Y, Z, …]) are rebuilt from the
slots for diagnostics and tests.
"""
from __future__ import annotations

import math

import torch
import warp as wp

from ..runtime import ensure_warp
from ..config import SimConfig
from .layout import EMPTY_BOX, N_STATS, NEVER, STAT_FIRST_T, box_intersection, box_volume

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
    """Both slots in one buffer per quantity, so a kernel reaches either with one index
    (`transfer.slot_index`): nodes [0, X·Y·Z) are slot 0 (dense), the next |S| are slot 1 on S.

    `mp` [X, Y, Z, 4] packs (p, m) so P2G scatters both with one 16-byte atomic, `vel` [X, Y, Z, 3];
    with two fields, `mp1` [Sx, Sy, Sz, 4], `vel1` [Sx, Sy, Sz, 3] and `mb` [2, Sx, Sy, Sz] (band
    mass of both fields, read only on S) live on the shared box `support`."""

    def __init__(self, origin, dx: float, shape, n_fields: int, device: str):
        ensure_warp()
        self.origin = tuple(float(o) for o in origin)
        self.dx = float(dx)
        self.shape = tuple(int(s) for s in shape)
        if min(self.shape) < 5:
            raise ValueError(f"sim.grid_shape {self.shape} is too small; every axis needs at least 5 nodes")
        self.n_fields = n_fields
        self.device = device
        self.contact_stats = torch.zeros(N_STATS, dtype=torch.float32, device=device)
        self.contact_stats[STAT_FIRST_T] = NEVER
        self.wp = dict(stats=wp.from_torch(self.contact_stats))
        self._capacity = -1
        self.set_boxes((0, 0, 0) + self.shape, EMPTY_BOX)
        self.ensure()

    # ---- the shared box -------------------------------------------------------------------------
    def set_boxes(self, box0: tuple, box1: tuple) -> None:
        """Field boxes B⁰, B¹ (node ranges the fields can occupy); slot 1 moves to S = B⁰ ∩ B¹,
        sized when a kernel first needs it (`ensure`), so a box replaced before any launch costs
        nothing. Slot 1 starts zeroed; the caller clears slot 0 where it matters."""
        self.boxes = (tuple(box0), tuple(box1))
        self.support = box_intersection(box0, box1) if self.n_fields > 1 else EMPTY_BOX
        self.wp_support = (wp.vec3i(*self.support[:3]), wp.vec3i(*self.support[3:]))
        self.wp_boxes = [wp.vec3i(*c) for b in self.boxes for c in (b[:3], b[3:])]  # lo0, hi0, lo1, hi1
        self._stale = True

    def ensure(self) -> None:
        """Buffers for slot 0 and slot 1 on S: reallocated (zeroed) when S outgrows them or falls
        under a quarter of them, which happens only between frames (boxes change there)."""
        if not self._stale:
            return
        self._stale = False
        n0 = self.shape[0] * self.shape[1] * self.shape[2]
        dims = tuple(max(0, self.support[i + 3] - self.support[i]) for i in range(3))
        n = dims[0] * dims[1] * dims[2]
        if n > self._capacity or 4 * n < self._capacity:
            self._capacity = n
            self._mp = torch.zeros((n0 + n, 4), dtype=torch.float32, device=self.device)
            self._vel = torch.zeros((n0 + n, 3), dtype=torch.float32, device=self.device)
            self._mb = torch.zeros(max(1, 2 * n), dtype=torch.float32, device=self.device)
        self.mp = self._mp[:n0].view(*self.shape, 4)
        self.vel = self._vel[:n0].view(*self.shape, 3)
        self.mp1 = self._mp[n0:n0 + n].view(*dims, 4)
        self.vel1 = self._vel[n0:n0 + n].view(*dims, 3)
        self.mb = self._mb[:2 * n].view(2, *dims)
        for t in (self.mp1, self.vel1, self.mb):
            t.zero_()
        self.wp.update(mp=wp.from_torch(self._mp[:n0 + n], dtype=wp.vec4), vel=wp.from_torch(self._vel[:n0 + n], dtype=wp.vec3),
                       mb=wp.from_torch(self._mb[:max(1, 2 * n)]))

    def clear(self) -> None:
        """Reset every accumulator (of slot 1 on the current S)."""
        self.ensure()
        self.mp.zero_()
        self.mp1.zero_()
        self.mb.zero_()

    def zero(self) -> None:
        """Reset accumulators and velocities (after a box change no stale node may survive)."""
        self.clear()
        self.vel.zero_()
        self.vel1.zero_()

    # ---- logical fields [K, X, Y, Z, …] (diagnostics and tests) ---------------------------------
    def _expand(self, slot0: torch.Tensor, slot1: torch.Tensor) -> torch.Tensor:
        """Field k at every node: field 0 is slot 0 inside B⁰; field 1 is slot 1 on S and slot 0
        on B¹ \\ B⁰."""
        if self.n_fields == 1:
            return slot0[None]
        out = torch.zeros((2, *slot0.shape), dtype=slot0.dtype, device=slot0.device)
        in0, in1 = self._mask(self.boxes[0]), self._mask(self.boxes[1])
        shape = in0.shape + (1,) * (slot0.dim() - 3)
        out[0] = slot0 * in0.view(shape)
        out[1] = slot0 * (in1 & ~in0).view(shape)
        s = self.support
        if box_volume(s) > 0:
            out[1, s[0]:s[3], s[1]:s[4], s[2]:s[5]] += slot1
        return out

    def _mask(self, box: tuple) -> torch.Tensor:
        m = torch.zeros(self.shape, dtype=torch.bool, device=self.mp.device)
        m[box[0]:box[3], box[1]:box[4], box[2]:box[5]] = True
        return m

    @property
    def mass(self) -> torch.Tensor:  # [K, X, Y, Z]
        self.ensure()
        return self._expand(self.mp[..., 3], self.mp1[..., 3])

    @property
    def momentum(self) -> torch.Tensor:  # [K, X, Y, Z, 3]
        self.ensure()
        return self._expand(self.mp[..., :3], self.mp1[..., :3])

    @property
    def velocity(self) -> torch.Tensor:  # [K, X, Y, Z, 3]
        self.ensure()
        return self._expand(self.vel, self.vel1)

    @property
    def band_mass(self) -> torch.Tensor:  # [K, X, Y, Z], zero outside S (read only there)
        if self.n_fields == 1:
            return torch.zeros((1, *self.shape), dtype=torch.float32, device=self.mp.device)
        self.ensure()
        out = torch.zeros((2, *self.shape), dtype=torch.float32, device=self.mp.device)
        s = self.support
        if box_volume(s) > 0:
            out[:, s[0]:s[3], s[1]:s[4], s[2]:s[5]] = self.mb
        return out

    @property
    def nbytes(self) -> int:
        """Grid-buffer footprint (slot 0, slot 1 and band mass as allocated) in bytes."""
        self.ensure()
        return sum(t.numel() * t.element_size() for t in (self._mp, self._vel, self._mb))
