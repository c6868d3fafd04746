"""`SlotStorage`: the host side of the slot storage of fragment fields (`sim.grid_storage = "slots"`), mixed
into `Simulator`.

After a latch the slot storage keeps slot 0 of every node in the dense grid and extra slots in a pool of
multi-fragment nodes (`fields.Grid`). What the host decides per frame lives here: which particles are "solo"
(no other fragment can reach their stencil: no slot claims), the fan-out capacity and launch order of the
others on a GPU, P2G's run length, and the pool pass (mass-gradient normals, then normalization, contact
and boundaries of every field at a pool row).
"""

from __future__ import annotations

from typing import Optional

import torch
import warp as wp

from ..neighbourhood import solo_mask, solo_radius
from ..physics.contact import NORMAL_MASS_GRADIENT
from .kernels import grid_update_pool
from .normal_kernels import pool_mass_gradients


class SlotStorage:
    """Solo flags, fan-out and the pool pass of the slot storage (mixed into `Simulator`)."""

    def _update_solo(self, travel: float) -> None:
        """Mark the particles no other fragment can reach this frame ("solo": every node of their stencil
        holds their fragment only, so P2G and G2P take the dense path with no slot claims; bitwise the
        same fields): no particle of another fragment within 4Δx + twice the travel (and the box slack)."""
        P, g = self.particles, self.grid
        reach = 4.0 * g.dx + 2.0 * travel + self.box_slack * g.dx
        r = solo_radius(reach, g.dx)  # the mask depends on the reach only through r; None: nobody is solo

        def query():
            return solo_mask(P.x, P.fragment, g.origin, g.dx, g.shape, reach)

        key = (r, P.x.data_ptr(), P.fragment.data_ptr())  # on CUDA one recorded graph per r (`recorded.py`)
        self.set_solo(None if r is None else self._queries(key, query) if self.use_graphs else query())

    def set_solo(self, mask: Optional[torch.Tensor]) -> None:
        """Set the solo flags (None: no particle is solo) and, with `slow_first` or `fanout`, the launch order,
        which must list exactly the particles that are not solo first (device ops; with `fanout` one host read
        of their count, which sizes the fan-out launches and P2G's slot cache). Set them only here: flags
        changed behind it would make P2G and G2P skip particles."""
        if mask is None:
            self.solo.zero_()
        else:
            self.solo.copy_(mask)
        if self.slow_first or self.fanout:
            self._order.copy_(torch.argsort(self.solo, stable=True))
            self._first.copy_((self.solo == 0).sum().view(1))
        if self.fanout:
            # None (a latch, a reorder, a redo on the whole grid) fans nothing out until the next frame's flags
            n = len(self.particles) if mask is None else int(self._first)  # the frame's second host read
            self._slow = n
            flagged = mask is not None and self.multifield and n > 0
            self._fan_cap = min(len(self.particles), max(256, 1 << (n - 1).bit_length())) if flagged else 0
            if self._slot_cache.numel() != max(1, 27 * self._fan_cap):  # sized with the capacity (graphs record anew)
                self._slot_cache = torch.empty(max(1, 27 * self._fan_cap), dtype=torch.int32, device=self.device)
                self.wp["slot_cache"] = wp.from_torch(self._slot_cache)

    def _fans_out(self, multi: int, only_fragment: int, gather: bool = False) -> bool:
        """Whether the particles that are not solo take `fanout_kernels` (multi-field grids with a fan-out
        capacity, on a GPU by default; not in the global fragment pass); `gather`: in G2P, where it also
        needs them to be few (at most `g2p_fanout_max` of the particles)."""
        few = not gather or self._slow <= self.g2p_fanout_max * len(self.particles)
        return bool(self.fanout and multi and only_fragment < 0 and self._fan_cap > 0 and few)

    def _run_length(self, multi: int) -> int:
        """Particles per thread of P2G's runs: `p2g_run`, or 0 (one per thread) on a multi-field grid where
        more than half of the particles take the slot path (the runs then only cost: BENCHMARKS.md)."""
        return self.p2g_run if not multi or 2 * self._slow <= len(self.particles) else 0

    def _split(self, multi: int) -> bool:
        """Whether G2P launches the particles that are not solo first (multi-field grids, on a GPU by
        default: on the CPU a single thread runs every launch in order, so it only costs)."""
        return bool(self.slow_first and multi)

    def _update_pool(self) -> None:
        """Pool rows: mass-gradient normals (if used), then every field's normalization, contact, boundaries."""
        g, multi = self.grid, int(self.multifield)
        c = self.cfg.contact
        grad0 = self._pool_gradient_buffer()
        if self.normal_mode == NORMAL_MASS_GRADIENT:
            self._launch(pool_mass_gradients, g.capacity * g.slots, [g.view, self.eps_m, grad0])
        gate = [multi, int(self.spec.contact), self.normal_mode, self._normal, self.wp["centroids"]]
        law = [
            float(self.cfg.restitution),
            float(c.friction),
            self.clock.view,
            self._gravity,
            self.boundaries.colliders,
        ]
        record = [int(self.record_contact), g.wp["stats"], g.wp["pair_stats"], g.pair_fragments, grad0]
        inputs = [g.view, self.eps_m, self.eps_b, c.fill * self.node_mass] + gate + law + record
        self._launch(grid_update_pool, g.capacity, inputs)

    def _pool_gradient_buffer(self):
        """[capacity] vec3 for ∇m of each pool row's slot-0 field (`normal_kernels`), sized with the pool:
        between frames by `fit_active_box`, so never inside a graph capture."""
        if self._grad0 is None or self._grad0.shape[0] != self.grid.capacity:
            self._grad0 = torch.zeros(max(1, self.grid.capacity), 3, dtype=torch.float32, device=self.device)
            self.wp["grad0"] = wp.from_torch(self._grad0, dtype=wp.vec3)
        return self.wp["grad0"]
