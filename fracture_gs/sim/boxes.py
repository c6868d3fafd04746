"""`FragmentBoxes`: the host side of `box_kernels` — a dense box per fragment, fitted to its particles.

A building block of the storage planned in docs/DESIGN.md ("Grid storage: per-fragment boxes (plan)"),
not yet what `Simulator` uses: it holds K boxes in one buffer and launches P2G, normalization, contact,
boundaries and G2P on them, so the plan's claim (every particle on a dense path, contact only where
fields meet) can be checked against the float64 twins and the shared-field transfer, and timed against
the slot storage (`apps/bench_fragments.py --boxes`), before the solver is moved onto it.
"""

from __future__ import annotations

import torch
import warp as wp

from ..runtime import ensure_warp, launch
from .box_kernels import BoxView, box_boundaries, box_contact, box_g2p, box_gradients, box_normalize, box_p2g_runs
from .contact import NORMAL_LATCHED, NORMAL_MASS_GRADIENT


class FragmentBoxes:
    """K dense boxes on a grid of `shape` nodes at `origin` with spacing `dx` (one buffer, box k from
    `offset[k]`). `fit` sizes them for the particles; the transfer methods take Warp views of the
    particle arrays (as `Simulator.wp` holds them)."""

    def __init__(self, shape, origin, dx: float, device: str = "cpu"):
        ensure_warp()
        self.shape, self.origin, self.dx, self.device = tuple(int(s) for s in shape), tuple(origin), float(dx), device
        self.capacity = 0
        self.lo = self.dims = self.offset = None
        self.nodes = 0
        self._no_stats = None  # a 1-element array for the contact kernel's statistics when none are kept

    def fit(self, x: torch.Tensor, fragment: torch.Tensor, slack: int = 1) -> None:  # [N, 3], [N]
        """Box k: the bounding box of fragment k's stencils plus `slack` nodes each way, inside the grid.
        One host read (the box sizes); the buffers grow only when the boxes need more nodes."""
        dev = x.device
        k = fragment.long().clamp_min(0)
        K = int(k.max()) + 1 if k.numel() else 1
        base = torch.floor((x.double() - torch.tensor(self.origin, dtype=torch.float64, device=dev)) / self.dx - 0.5)
        base = base.long()
        idx = k[:, None].expand(-1, 3)
        big = 1 << 30
        lo = torch.full((K, 3), big, dtype=torch.long, device=dev).scatter_reduce_(0, idx, base, "amin")
        hi = torch.full((K, 3), -big, dtype=torch.long, device=dev).scatter_reduce_(0, idx, base + 2, "amax")
        empty = lo[:, 0] == big
        lo[empty], hi[empty] = 0, 0
        top = torch.tensor(self.shape, device=dev) - 1
        lo = torch.minimum(torch.maximum(lo - slack, torch.zeros_like(lo)), top)
        hi = torch.minimum(torch.maximum(hi + slack, lo), top)
        dims = (hi - lo + 1).cpu()
        sizes = dims.prod(1)
        offset = torch.zeros(K + 1, dtype=torch.long)
        offset[1:] = torch.cumsum(sizes, 0)
        self.nodes = int(offset[-1])
        if self.nodes > self.capacity:
            self.capacity = max(self.nodes, 2 * self.capacity)
            self.mp = torch.zeros(self.capacity, 4, dtype=torch.float32, device=self.device)
            self.vel = torch.zeros(self.capacity, 3, dtype=torch.float32, device=self.device)
            self.grad = torch.zeros(self.capacity, 3, dtype=torch.float32, device=self.device)
            self.band = torch.zeros(self.capacity, dtype=torch.float32, device=self.device)
            self.box_of = torch.zeros(self.capacity, dtype=torch.int32, device=self.device)
        self.box_of[: self.nodes] = torch.repeat_interleave(torch.arange(K, dtype=torch.int32), sizes).to(self.device)
        self.lo = lo.to(self.device, torch.int32).contiguous()
        self.dims = dims.to(self.device, torch.int32).contiguous()
        self.offset = offset.to(self.device, torch.int32)
        self.K = K
        v = BoxView()
        v.lo, v.dims = wp.from_torch(self.lo, dtype=wp.vec3i), wp.from_torch(self.dims, dtype=wp.vec3i)
        v.offset, v.box_of = wp.from_torch(self.offset), wp.from_torch(self.box_of[: self.nodes])
        v.mp, v.vel = (
            wp.from_torch(self.mp[: self.nodes], dtype=wp.vec4),
            wp.from_torch(self.vel[: self.nodes], dtype=wp.vec3),
        )
        v.grad = wp.from_torch(self.grad[: self.nodes], dtype=wp.vec3)
        v.band = wp.from_torch(self.band[: self.nodes])
        v.origin, v.dx, v.inv_dx = wp.vec3(*self.origin), self.dx, 1.0 / self.dx
        v.shape, v.boxes = wp.vec3i(*self.shape), K
        self.view = v

    def p2g(self, w: dict, dt: float, counts, run: int = 0) -> None:
        """Clear the boxes, then every particle's deposit into its fragment's box. `w`: Warp arrays x, v, C,
        mass, volume, stress, fragment, band; `counts`: the escape counter's array; `run` > 0: that many
        consecutive particles a thread, summed in registers while they share fragment and stencil base
        (particles sorted by cell)."""
        self.mp[: self.nodes].zero_()
        self.band[: self.nodes].zero_()
        n = w["x"].shape[0]
        keys = ("x", "v", "C", "mass", "volume", "stress", "fragment", "band")
        run = max(1, int(run))
        launch(box_p2g_runs, -(-n // run), [w[k] for k in keys] + [float(dt), self.view, run, counts], self.device)

    def update(
        self,
        dt: float,
        eps_m: float,
        gravity,
        fill_mass: float,
        centroids,
        counts,
        e=0.0,
        mu=0.0,
        colliders=None,
        t=0.0,
        latched=None,
        eps_b: float = 0.0,
        project: bool = True,
        stats=None,
        mass_gradient=None,
    ) -> None:
        """Every field's v = p/m + Δt g, then contact where fields meet, then with `colliders`
        (`boundary.Colliders`) the boundaries at time t. Contact: with `latched` (n_Π, a 3-tuple) along it
        where both fields' band masses exceed `eps_b` (the paper's gate); else along the fields' mass
        gradients where m_a + m_b ≥ fill_mass (`centroids` [K] vec3 Warp array: the normals' fallback).
        `mass_gradient` True takes the mass-gradient normals with `latched` as their last fallback. `project`
        False detects approach without projecting (Local Multi-Field); `stats` = (stats, pair_stats, K), Warp
        arrays laid out as the grid's contact statistics, accumulates them."""
        launch(box_normalize, self.nodes, [self.view, float(eps_m), float(dt), wp.vec3(*gravity)], self.device)
        launch(box_gradients, self.nodes, [self.view, float(eps_m)], self.device)
        by_gradient = latched is None if mass_gradient is None else mass_gradient
        mode = NORMAL_MASS_GRADIENT if by_gradient else NORMAL_LATCHED
        n = wp.vec3(*(latched if latched is not None else (0.0, 0.0, 1.0)))
        if stats is None:  # made once: no allocation per substep
            if self._no_stats is None:
                self._no_stats = wp.zeros(1, dtype=float, device=self.device)
            stats = (self._no_stats, self._no_stats, 0)
        inputs = [self.view, float(eps_m), float(eps_b), float(fill_mass), mode, n, centroids, float(e), float(mu)]
        inputs += [int(project), int(stats[2] > 0), float(t), stats[0], stats[1], int(stats[2]), counts]
        launch(box_contact, self.nodes, inputs, self.device)
        if colliders is not None:
            launch(box_boundaries, self.nodes, [self.view, float(eps_m), float(t), colliders], self.device)

    def g2p(self, w: dict, dt: float, lower, upper, counts) -> None:
        """Every particle gathers from its own fragment's box (v, C, F, x; clamped into [lower, upper])."""
        keys = ("x", "v", "C", "F", "fragment")
        launch(
            box_g2p, w["x"].shape[0], [w[k] for k in keys] + [float(dt), self.view, lower, upper, counts], self.device
        )

    def field(self, k: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Box k's mass [X,Y,Z], momentum [X,Y,Z,3] and velocity [X,Y,Z,3] (its lowest node: `lo[k]`)."""
        a, b = int(self.offset[k]), int(self.offset[k + 1])
        d = [int(s) for s in self.dims[k]]
        return self.mp[a:b, 3].reshape(d), self.mp[a:b, :3].reshape(*d, 3), self.vel[a:b].reshape(*d, 3)
