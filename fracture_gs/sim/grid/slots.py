"""`SlotStorage`: the dense grid's substep, and after a latch the slot storage of fragment fields
(`sim.grid_storage = "slots"`): a `storage.Storage`.

Before a latch (and for the shared variants) every particle deposits into and gathers from slot 0, the dense field,
over the active box of nodes (`fit`: the particles' bounding box plus the stencil, the travel and the slack). After
a latch the slot storage keeps slot 0 of every node in the dense grid and extra slots in a pool of multi-fragment
nodes (`fields.Grid`). What the host decides per frame lives here: the active box, which particles are "solo" (no
other fragment can reach their stencil: no slot claims), the fan-out capacity and launch order of the others on a
GPU, P2G's run length, and the pool pass (mass-gradient normals, then normalization, contact and boundaries of every
field at a pool row) beside the dense pass.
"""

from __future__ import annotations

import math
import weakref
from typing import Optional

import torch
import warp as wp

from ...runtime import range_views
from ..neighbourhood import solo_mask, solo_radius
from ..physics.contact import NORMAL_LATCHED, NORMAL_MASS_GRADIENT
from ..recorded import Recorded
from ..storage import Storage
from .fanout_kernels import LANES, g2p_fanout, p2g_fanout
from .kernels import clear_dense, clear_pool, g2p, grid_update_dense, grid_update_pool, p2g
from .normal_kernels import pool_mass_gradients
from .run_kernels import p2g_runs


class SlotStorage(Storage):
    """The dense grid `sim.grid` with its slots and pool, driven for simulator `sim` (held weakly)."""

    def __init__(self, sim):
        self.sim = weakref.proxy(sim)  # the simulator owns its storage: no reference cycle
        self.grid = sim.grid
        n, device = len(sim.particles), sim.device
        self.solo = torch.zeros(n, dtype=torch.int32, device=device)  # see `update_solo`
        self.queries = Recorded(device)  # CUDA: the per-frame solo mask as recorded graphs
        self._zeros = torch.zeros(n, dtype=torch.int32, device=device)  # a per-particle flag that reads 0
        # The particles that are not solo (1.6 % at K = 2 on the Table 2 ficus) do 27 serial slot lookups each; on a
        # GPU their threads finished long after the dense bulk. With `options.fanout` each of them gets one thread per
        # stencil node in P2G, and a warp in G2P while they are at most `options.g2p_fanout_max` of the particles
        # (`fanout_kernels`). The launches cover a power-of-two capacity ≥ their count, read once per frame in
        # `set_solo` (graphs record again only when it changes). `options.slow_first`, the earlier remedy, launches
        # them first in G2P otherwise.
        self.slow = n  # particles that are not solo (every one until the first flags)
        self.fan_cap = 0
        # buffer index of every (listed particle, stencil node) that P2G's fan-out deposited into, read back by G2P in
        # the same substep instead of looking the slot up again
        self.slot_cache = torch.zeros(1, dtype=torch.int32, device=device)
        self.order = torch.arange(n, dtype=torch.int32, device=device)  # the particles that are not solo first
        self.first = torch.full((1,), n, dtype=torch.int32, device=device)  # how many are not solo
        self.grad0 = None  # see `pool_gradient_buffer`
        self.pool_rows = 0  # multi-fragment nodes expected per substep (sizes the grid's pool)
        self.wp = {k: wp.from_torch(t) for k, t in (("solo", self.solo), ("zeros", self._zeros))}
        self.wp.update(order=wp.from_torch(self.order), first=wp.from_torch(self.first))
        self.wp["slot_cache"] = wp.from_torch(self.slot_cache)
        self.reset_box()

    # ---- the grid work's box ------------------------------------------------------------------
    def reset_box(self) -> None:
        """Grid work over the whole grid (until `fit`)."""
        self.set_box((0, 0, 0) + tuple(self.grid.shape))

    def set_box(self, box: tuple) -> None:
        self.box = tuple(box)  # active node box (lo, hi): where grid work happens
        self.grid.box = self.box
        self._box_lo, self._box_hi = wp.vec3i(*box[:3]), wp.vec3i(*box[3:])

    def fit(self, lower, upper, travel: float, slack: int) -> None:
        """The active box: the particles' bounding box plus the stencil, the travel and the slack ("no work on empty
        grid"); the grid is cleared whenever the box changes so no stale node survives. After a latch also the pool
        (sized here, between frames) and the solo flags. P2G counts any particle whose stencil has left the box."""
        sim, g = self.sim, self.grid
        pad = 3 + math.ceil(travel / g.dx) + slack
        lo = [max(0, int(math.floor((float(lower[a]) - o) / g.dx)) - pad) for a, o in enumerate(g.origin)]
        hi = [
            min(s, int(math.floor((float(upper[a]) - o) / g.dx)) + 1 + pad)
            for a, (o, s) in enumerate(zip(g.origin, g.shape))
        ]
        box = tuple(lo) + tuple(hi)
        moved = g.ensure_pool(self.pool_rows) if sim.multifield else False
        if sim.multifield:
            self.pool_gradient_buffer()
        if box != self.box or moved:
            self.set_box(box)
            g.zero()
        if sim.multifield:
            self.update_solo(travel, slack)

    def whole_grid(self) -> bool:
        """The whole grid, where nothing can escape, and every particle claims its slots (no solo flags)."""
        if self.sim.multifield:
            self.grid.ensure_pool(self.pool_rows)
        self.reset_box()
        self.grid.zero()
        self.set_solo(None)
        return True

    def reset(self, bands: int) -> None:
        """A latch changed the routing (any variant): the pool expects the band's nodes (`bands` band particles),
        the grid work takes the whole grid and no particle is solo until the next frame's `fit`."""
        self.pool_rows = max(self.pool_rows, 4 * bands + len(self.sim.particles) // 64)
        self.reset_box()
        self.set_solo(None)

    def on_latch(self, slack: int) -> None:
        """Multi-field after a latch: a pool for the expected rows and an empty grid."""
        self.grid.ensure_pool(self.pool_rows)
        self.grid.zero()

    def frame_done(self, rows: int) -> None:
        """After a frame's check: the next pool expects the `rows` this frame used (shrinking by half at most)."""
        self.pool_rows = max(rows, self.pool_rows // 2)

    def grow_pool(self) -> None:
        """A pool overflow (the frame is redone): the next pool is twice the one that overflowed."""
        self.pool_rows = 2 * self.grid.capacity

    def graph_key(self) -> tuple:
        g = self.grid
        return (self.box, g.capacity, id(g.view), self.fan_cap, self.run_length(int(self.sim.multifield)))

    # ---- solo particles and the fan-out -------------------------------------------------------
    def update_solo(self, travel: float, slack: int) -> None:
        """Mark the particles no other fragment can reach this frame ("solo": every node of their stencil
        holds their fragment only, so P2G and G2P take the dense path with no slot claims; bitwise the
        same fields): no particle of another fragment within 4Δx + twice the travel (and `slack` cells)."""
        sim, g = self.sim, self.grid
        P = sim.particles
        reach = 4.0 * g.dx + 2.0 * travel + slack * g.dx
        r = solo_radius(reach, g.dx)  # the mask depends on the reach only through r; None: nobody is solo

        def query():
            return solo_mask(P.x, P.fragment, g.origin, g.dx, g.shape, reach)

        key = (r, P.x.data_ptr(), P.fragment.data_ptr())  # on CUDA one recorded graph per r (`recorded.py`)
        self.set_solo(None if r is None else self.queries(key, query) if sim.options.use_graphs else query())

    def set_solo(self, mask: Optional[torch.Tensor]) -> None:
        """Set the solo flags (None: no particle is solo) and, with `slow_first` or `fanout`, the launch order,
        which must list exactly the particles that are not solo first (device ops; with `fanout` one host read
        of their count, which sizes the fan-out launches and P2G's slot cache). Set them only here: flags
        changed behind it would make P2G and G2P skip particles."""
        sim = self.sim
        opt = sim.options
        if mask is None:
            self.solo.zero_()
        else:
            self.solo.copy_(mask)
        if opt.slow_first or opt.fanout:
            self.order.copy_(torch.argsort(self.solo, stable=True))
            self.first.copy_((self.solo == 0).sum().view(1))
        if opt.fanout:
            # None (a latch, a reorder, a redo on the whole grid) fans nothing out until the next frame's flags
            n = len(sim.particles) if mask is None else int(self.first)  # the frame's second host read
            self.slow = n
            flagged = mask is not None and sim.multifield and n > 0
            self.fan_cap = min(len(sim.particles), max(256, 1 << (n - 1).bit_length())) if flagged else 0
            if self.slot_cache.numel() != max(1, 27 * self.fan_cap):  # sized with the capacity (graphs record anew)
                self.slot_cache = torch.empty(max(1, 27 * self.fan_cap), dtype=torch.int32, device=sim.device)
                self.wp["slot_cache"] = wp.from_torch(self.slot_cache)

    def fans_out(self, multi: int, only_fragment: int, gather: bool = False) -> bool:
        """Whether the particles that are not solo take `fanout_kernels` (multi-field grids with a fan-out
        capacity, on a GPU by default; not in the global fragment pass); `gather`: in G2P, where it also
        needs them to be few (at most `g2p_fanout_max` of the particles)."""
        opt = self.sim.options
        few = not gather or self.slow <= opt.g2p_fanout_max * len(self.sim.particles)
        return bool(opt.fanout and multi and only_fragment < 0 and self.fan_cap > 0 and few)

    def run_length(self, multi: int) -> int:
        """Particles per thread of P2G's runs: `p2g_run`, or 0 (one per thread) on a multi-field grid where
        more than half of the particles take the slot path (the runs then only cost: BENCHMARKS.md)."""
        run = self.sim.options.p2g_run
        return run if not multi or 2 * self.slow <= len(self.sim.particles) else 0

    def split(self, multi: int) -> bool:
        """Whether G2P launches the particles that are not solo first (multi-field grids, on a GPU by
        default: on the CPU a single thread runs every launch in order, so it only costs)."""
        return bool(self.sim.options.slow_first and multi)

    # ---- the substep ----------------------------------------------------------------------------
    def p2g(self, only_fragment: int = -1, counts=None, target=None, multifield=None, stress=None) -> None:
        """Reset the active fields and scatter the particles into them. `target` (a Grid), `multifield` and `stress`
        (a Warp view) override the destination, the routing and the stress: the diagnostics' per-fragment shadow
        transfer."""
        sim = self.sim
        g, w, s = target or self.grid, sim.wp, self.wp
        multi = int(sim.multifield if multifield is None else multifield)
        fan = target is None and self.fans_out(multi, only_fragment)
        side = sim.beside(on=fan)  # the pool's reset and the fan-out beside the dense deposits
        if target is None:
            b = self.box
            sim.launch(clear_dense, (b[3] - b[0], b[4] - b[1], b[5] - b[2]), [g.view, self._box_lo])
            if multi:
                with side:
                    sim.launch(clear_pool, g.capacity, [g.view])
            lo, hi = self._box_lo, self._box_hi
        else:
            g.clear()
            lo, hi = wp.vec3i(0, 0, 0), wp.vec3i(*g.shape)
        run = self.run_length(multi) if target is None and only_fragment < 0 and (fan or not multi) else 0
        counts = w["counts"] if counts is None else counts
        particle_arrays = [w[k] for k in ("x", "v", "C", "mass", "volume")]  # what P2G reads of each particle
        # band particles give every node they reach a pool row holding their band mass, which only the contact
        # gate of latched normals reads: with mass-gradient normals (K > 2) their flags read 0 in P2G
        band = w["band"] if target is not None or sim.normal_mode == NORMAL_LATCHED else s["zeros"]
        particle_arrays += [w["stress"] if stress is None else stress, w["fragment"], band]
        n = len(sim.particles)
        if run > 0:  # `run_kernels.p2g_runs` takes only the first six: its particles are on the dense path
            extra = [s["solo"], multi, run, sim.clock.view, g.view, lo, hi, counts]
            sim.launch(p2g_runs, -(-n // run), particle_arrays[:6] + extra)
        else:
            extra = [s["solo"] if target is None else s["zeros"], multi, only_fragment, int(fan), sim.clock.view]
            extra += [g.view, lo, hi, counts]
            sim.launch(p2g, n, particle_arrays + extra)
        if fan:
            extra = [s["order"], s["first"], s["slot_cache"], sim.clock.view, g.view, counts]
            with side:
                sim.launch(p2g_fanout, 27 * self.fan_cap, particle_arrays + extra)
            sim.fork.join()

    def update(self) -> None:
        """Slot 0 of every node without a pool row (`grid_update_dense`) and, beside it, the pool pass."""
        sim, g, multi = self.sim, self.grid, int(self.sim.multifield)
        if multi:  # the nodes with a pool row, beside the dense pass (they write disjoint nodes)
            with sim.beside():
                self.update_pool()
        b = self.box
        dense = [g.view, self._box_lo, multi, sim.eps_m, sim.clock.view, sim.gravity, sim.boundaries.colliders]
        sim.launch(grid_update_dense, (b[3] - b[0], b[4] - b[1], b[5] - b[2]), dense)
        sim.fork.join()

    def update_pool(self) -> None:
        """Pool rows: mass-gradient normals (if used), then every field's normalization, contact, boundaries."""
        sim, g, multi = self.sim, self.grid, int(self.sim.multifield)
        c = sim.cfg.contact
        grad0 = self.pool_gradient_buffer()
        if sim.normal_mode == NORMAL_MASS_GRADIENT:
            sim.launch(pool_mass_gradients, g.capacity * g.slots, [g.view, sim.eps_m, grad0])
        gate = [multi, int(sim.spec.contact), sim.normal_mode, sim.latched_normal, sim.wp["centroids"]]
        law = [float(sim.cfg.restitution), float(c.friction), sim.clock.view, sim.gravity, sim.boundaries.colliders]
        record = [int(sim.record_contact), g.wp["stats"], g.wp["pair_stats"], g.pair_fragments, grad0]
        inputs = [g.view, sim.eps_m, sim.eps_b, c.fill * sim.node_mass] + gate + law + record
        sim.launch(grid_update_pool, g.capacity, inputs)

    def pool_gradient_buffer(self):
        """[capacity] vec3 for ∇m of each pool row's slot-0 field (`normal_kernels`), sized with the pool:
        between frames by `fit`, so never inside a graph capture."""
        if self.grad0 is None or self.grad0.shape[0] != self.grid.capacity:
            self.grad0 = torch.zeros(max(1, self.grid.capacity), 3, dtype=torch.float32, device=self.sim.device)
            self.wp["grad0"] = wp.from_torch(self.grad0, dtype=wp.vec3)
        return self.wp["grad0"]

    def g2p(self, only_fragment: int = -1) -> None:
        """Each particle's own field, from slot 0 (solo) or its slots; with the fan-out the listed particles a warp
        each. Per particle but for the clamp counter: on the CPU one launch per core's share (`Simulator.per_range`)."""
        sim = self.sim
        g, w, s = self.grid, sim.wp, self.wp
        arrays = [w["x"], w["v"], w["C"], w["F"], w["fragment"], s["solo"]]
        multi = int(sim.multifield)
        fan = self.fans_out(multi, only_fragment, gather=True)
        split = self.split(multi) and not fan
        cached = int(self.fans_out(multi, only_fragment))  # this substep's P2G filled the slot cache

        def launch(a: int, b: int, counts) -> None:
            sim.launch(
                g2p,
                (b - a) * (2 if split else 1),
                range_views(arrays, a, b)
                + [s["order"], s["first"], int(split), int(fan), s["slot_cache"], cached]
                + [multi, only_fragment, sim.clock.view, g.view, sim.lower, sim.upper, counts],
            )

        if fan:  # with `one_gather` the solo particles too, in the same launch behind the listed ones
            listed = LANES * self.fan_cap if sim.options.one_gather else 0
            sim.launch(
                g2p_fanout,
                LANES * self.fan_cap + (len(sim.particles) if listed else 0),
                arrays[:5]
                + [s["order"], s["first"], s["slot_cache"], cached, int(sim.device.startswith("cuda"))]
                + [sim.clock.view, g.view]
                + [sim.lower, sim.upper, w["counts"], s["solo"], listed],
            )
            if listed:
                return
        sim.per_range(launch, split)
