"""`FragmentBoxes`: the host side of `kernels` — a dense box per fragment, fitted to its particles.

The multi-field grid storage of `Simulator` with `sim.grid_storage = "boxes"` (docs/DESIGN.md "Grid storage:
per-fragment boxes"): K boxes in one buffer, refitted every frame, and the launches of a substep on them
(clear, P2G, the grid update with contact where fields meet, G2P). Buffers are made for `max_fragments`
boxes and a node capacity that only grows, so the launches a CUDA graph records stay valid while the boxes
move: a fit changes the recorded launches only when the capacity grows (`layout_key`).
"""

from __future__ import annotations

import torch
import warp as wp

from ...runtime import ensure_warp, launch, range_views
from ..physics.contact import NORMAL_LATCHED, NORMAL_MASS_GRADIENT
from .kernels import BOX_P2G, MAX_FIELDS, BoxContact, BoxView, box_clear, box_g2p, fragment_bounds, grid_update_kernel

GROWTH = 1.25  # capacity headroom when the boxes outgrow the buffer
BOUNDS_RUN = 32  # consecutive particles a thread of `fragment_bounds` reduces before its atomics


class FragmentBoxes:
    """Up to `max_fragments` dense boxes on a grid of `shape` nodes at `origin` with spacing `dx`. `fit` sizes
    them for the particles; the transfer methods take Warp views of the particle arrays (as `Simulator.wp`
    holds them) and the frame clock (`clock.FrameClock.view`: Δt and t on the device)."""

    def __init__(self, shape, origin, dx: float, device: str = "cpu", max_fragments: int = 64):
        ensure_warp()
        self.shape, self.origin, self.dx, self.device = tuple(int(s) for s in shape), tuple(origin), float(dx), device
        self.max_fragments = K = int(max_fragments)
        self.lo = torch.zeros(K, 3, dtype=torch.int32, device=device)
        self.dims = torch.ones(K, 3, dtype=torch.int32, device=device)
        self.offset = torch.zeros(K + 1, dtype=torch.int32, device=device)
        self.over_start = torch.zeros(K + 1, dtype=torch.int32, device=device)
        self._grow_overlaps(64)  # entries of the overlap lists: grown with the pairs of boxes that overlap
        self.capacity = 0
        self.nodes = 0
        self.K = 0
        self.view = None
        self._no_stats = wp.zeros(1, dtype=float, device=device)  # the statistics' arrays when none are kept
        self._top = torch.tensor(self.shape, device=device) - 1  # the grid's last node per axis

    def _grow_overlaps(self, n: int) -> None:
        """Room for n entries of the overlap lists (their number follows the overlapping pairs, O(K), not
        max_fragments²)."""
        dev = self.device
        self.over = torch.zeros(n, dtype=torch.int32, device=dev)
        self.over_lo = torch.zeros(n, 3, dtype=torch.int32, device=dev)
        self.over_dims = torch.zeros(n, 3, dtype=torch.int32, device=dev)
        self.over_off = torch.zeros(n, dtype=torch.int32, device=dev)

    @property
    def nbytes(self) -> int:
        """Bytes of the box buffers: (p, m), v, the band mass and the box of every node."""
        return self.capacity * (16 + 12 + 4 + 4)

    @property
    def layout_key(self) -> tuple:
        """What recorded launches bake in: the buffers (node capacity, overlap-list room) and the number of
        boxes."""
        return (self.capacity, self.over.numel(), self.K)

    def fit(self, x: torch.Tensor, fragment: torch.Tensor, slack: int = 1, K: int = 0) -> bool:  # [N, 3], [N]
        """Box k: the bounding box of fragment k's stencils plus `slack` nodes each way, inside the grid, for
        k < K (default: the largest id + 1, a host read). Device work and two host reads (the node total, and
        the overlap lists' length in `nonzero`); returns whether the buffers grew (recorded launches must then
        be recorded again)."""
        dev = x.device
        K = max(int(K), 1) if K else (int(fragment.max().clamp_min(0)) + 1 if fragment.numel() else 1)
        if K > self.max_fragments:
            raise ValueError(f"{K} fragments do not fit {self.max_fragments} boxes")
        big = 1 << 30
        lo = torch.full((K, 3), big, dtype=torch.int32, device=dev)
        hi = torch.full((K, 3), -big, dtype=torch.int32, device=dev)
        if len(x):
            xs = wp.from_torch(x.contiguous(), dtype=wp.vec3)
            ks = wp.from_torch(fragment.to(torch.int32).contiguous())
            inputs = [xs, ks, wp.vec3d(*self.origin), self.dx, BOUNDS_RUN, wp.from_torch(lo), wp.from_torch(hi)]
            launch(fragment_bounds, -(-len(x) // BOUNDS_RUN), inputs, self.device)
        lo, hi = lo.long(), hi.long()
        empty = (lo[:, 0] == big)[:, None]
        lo, hi = torch.where(empty, 0, lo), torch.where(empty, 0, hi)
        top = self._top.to(dev)
        lo = (lo - slack).clamp_min(0).minimum(top)
        hi = torch.maximum((hi + slack).minimum(top), lo)
        dims = hi - lo + 1  # [K, 3]
        offset = torch.zeros(K + 1, dtype=torch.long, device=dev)
        offset[1:] = torch.cumsum(dims.prod(1), 0)
        # boxes that overlap box k (its contact partners), ascending
        meets = ((lo[:, None, :] <= hi[None, :, :]) & (lo[None, :, :] <= hi[:, None, :])).all(2)
        meets &= ~torch.eye(K, dtype=torch.bool, device=dev)
        over_start = torch.zeros(K + 1, dtype=torch.long, device=dev)
        over_start[1:] = torch.cumsum(meets.sum(1), 0)
        pairs = meets.nonzero()[:, 1]  # row-major: box k's partners in ascending order
        self.nodes = int(offset[-1])  # the host read
        grew = self.nodes > self.capacity
        if grew:
            self.capacity = max(self.nodes, int(GROWTH * self.nodes))
            self.mp = torch.zeros(self.capacity, 4, dtype=torch.float32, device=self.device)
            self.vel = torch.zeros(self.capacity, 3, dtype=torch.float32, device=self.device)
            self.band = torch.zeros(self.capacity, dtype=torch.float32, device=self.device)
            self.box_of = torch.full((self.capacity,), -1, dtype=torch.int32, device=self.device)
        self.lo[:K].copy_(lo)
        self.dims[:K].copy_(dims)
        self.offset[: K + 1].copy_(offset)
        self.over_start[: K + 1].copy_(over_start)
        relist = len(pairs) > self.over.numel()
        if relist:
            self._grow_overlaps(max(len(pairs), 2 * self.over.numel()))
        self.over[: len(pairs)].copy_(pairs)
        self.over_lo[: len(pairs)].copy_(lo[pairs])
        self.over_dims[: len(pairs)].copy_(dims[pairs])
        self.over_off[: len(pairs)].copy_(offset[pairs])
        where = torch.arange(self.capacity, device=self.device)
        box = torch.searchsorted(offset[1:], where, right=True)
        self.box_of.copy_(torch.where(box < K, box, -1))
        self.mp.zero_()  # the boxes moved: P2G starts from empty fields (afterwards `clear` empties them)
        self.band.zero_()
        self.vel.zero_()  # nodes no particle reaches keep v = 0 (the grid update writes only where m > 0)
        if grew or relist or K != self.K:
            self.K = K
            self._make_view()
        return grew or relist

    def _make_view(self) -> None:
        v = BoxView()
        v.lo, v.dims = wp.from_torch(self.lo, dtype=wp.vec3i), wp.from_torch(self.dims, dtype=wp.vec3i)
        v.offset, v.box_of = wp.from_torch(self.offset), wp.from_torch(self.box_of)
        v.over_start, v.over = wp.from_torch(self.over_start), wp.from_torch(self.over)
        v.over_lo, v.over_dims = (
            wp.from_torch(self.over_lo, dtype=wp.vec3i),
            wp.from_torch(self.over_dims, dtype=wp.vec3i),
        )
        v.over_off = wp.from_torch(self.over_off)
        v.mp, v.vel = wp.from_torch(self.mp, dtype=wp.vec4), wp.from_torch(self.vel, dtype=wp.vec3)
        v.band = wp.from_torch(self.band)
        v.origin, v.dx, v.inv_dx = wp.vec3(*self.origin), self.dx, 1.0 / self.dx
        v.shape = wp.vec3i(*self.shape)
        self.view = v

    def p2g(self, w: dict, clock, counts, run: int = 0, band_flags=None) -> None:
        """Every particle's deposit into its fragment's box, which the last `fit` or `clear` emptied. `w`: Warp
        arrays x, v, C, mass, volume, stress, fragment; `counts`: the escape counter's array; `run` > 0: that
        many consecutive particles a thread, summed in registers while they share fragment and stencil base
        (particles sorted by cell); `band_flags` ([N] int32 Warp array, γ_p ≠ 0): also each field's band mass
        from its band particles (only the latched normals' gate reads it), in the same pass."""
        n = w["x"].shape[0]
        arrays = [w[k] for k in ("x", "v", "C", "mass", "volume", "stress", "fragment")]
        run = max(1, int(run))
        flags = w["fragment"] if band_flags is None else band_flags
        inputs = arrays + [clock, self.view, run, counts, flags]
        launch(BOX_P2G[band_flags is not None], -(-n // run), inputs, self.device)

    def clear(self) -> None:
        """Empty every field (m, p, band mass) for the next P2G. G2P reads only velocities, so this may run
        beside it (`storage.BoxStorage.g2p`)."""
        launch(box_clear, self.capacity, [self.view], self.device)

    def update(
        self,
        clock,
        eps_m: float,
        gravity,
        fill_mass: float,
        centroids,
        counts,
        colliders,
        e: float = 0.0,
        mu: float = 0.0,
        latched=None,
        eps_b: float = 0.0,
        project: bool = True,
        stats=None,
        mass_gradient=None,
        slots: int = MAX_FIELDS,
        fast_math: bool | None = None,
    ) -> None:
        """Every field's v = p/m + Δt g, contact where fields meet, then the boundaries (`colliders`,
        `boundary.Colliders`); `gravity` and `latched` are 3-tuples or `wp.vec3`. Contact: with `latched`
        (n_Π) along it where both fields' band masses exceed `eps_b` (the paper's gate); else along the
        fields' mass gradients where m_a + m_b ≥ fill_mass (`centroids` [K] vec3 Warp array: the normals'
        fallback). `mass_gradient` True takes the mass-gradient normals with `latched` as their last
        fallback. `project` False detects approach without projecting (Local Multi-Field); `stats` = (stats,
        pair_stats, K), Warp arrays laid out as the grid's contact statistics, accumulates them; `slots`:
        fields a node's contact couples (more are counted); `fast_math`: the kernel compiled with fast math
        (default: on CUDA devices, not on the CPU)."""
        if not 2 <= slots <= MAX_FIELDS:
            raise ValueError(f"slots = {slots} must lie in [2, {MAX_FIELDS}]")
        by_gradient = latched is None if mass_gradient is None else mass_gradient
        mode = NORMAL_MASS_GRADIENT if by_gradient else NORMAL_LATCHED
        n = wp.vec3(*(latched if latched is not None else (0.0, 0.0, 1.0)))
        if stats is None:
            stats = (self._no_stats, self._no_stats, 0)
        c = BoxContact()
        c.eps_b, c.fill_mass, c.normal_mode, c.latched, c.centroids = float(eps_b), float(fill_mass), mode, n, centroids
        c.restitution, c.friction, c.project = float(e), float(mu), int(project)
        c.stats, c.pair_stats, c.n_fragments = stats[0], stats[1], int(stats[2])
        inputs = [self.view, c, float(eps_m), int(slots), clock, wp.vec3(*gravity), colliders, counts]
        fast = self.device != "cpu" if fast_math is None else fast_math
        launch(grid_update_kernel(bool(stats[2] > 0), fast, mode), self.capacity, inputs, self.device)

    def g2p(self, w: dict, clock, lower, upper, counts, a: int = 0, b: int = -1) -> None:
        """Particles [a, b) gather from their own fragment's box (v, C, F, x; clamped into [lower, upper])."""
        b = w["x"].shape[0] if b < 0 else b
        arrays = range_views([w[k] for k in ("x", "v", "C", "F", "fragment")], a, b)
        launch(box_g2p, b - a, arrays + [clock, self.view, lower, upper, counts], self.device)

    def field(self, k: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Box k's mass [X,Y,Z], momentum [X,Y,Z,3] and velocity [X,Y,Z,3] (its lowest node: `lo[k]`)."""
        a, b = int(self.offset[k]), int(self.offset[k + 1])
        d = [int(s) for s in self.dims[k]]
        return self.mp[a:b, 3].reshape(d), self.mp[a:b, :3].reshape(*d, 3), self.vel[a:b].reshape(*d, 3)

    def dense(self, K: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """Fields 0 … K−1 on the whole grid: mass [K, X, Y, Z], momentum [K, X, Y, Z, 3], velocity [K, X, Y, Z, 3]
        and band mass [K, X, Y, Z], zero outside each box (what the slot storage's grid views give)."""
        shape = self.shape
        m = torch.zeros((K, *shape), dtype=torch.float32, device=self.device)
        p = torch.zeros((K, *shape, 3), dtype=torch.float32, device=self.device)
        v = torch.zeros_like(p)
        band = torch.zeros_like(m)
        for k in range(min(K, self.K)):
            lo = [int(a) for a in self.lo[k]]
            a, b = int(self.offset[k]), int(self.offset[k + 1])
            d = [int(s) for s in self.dims[k]]
            at = (k, *(slice(lo[i], lo[i] + d[i]) for i in range(3)))
            m[at], p[at], v[at] = self.field(k)
            band[at] = self.band[a:b].reshape(d)
        return m, p, v, band
