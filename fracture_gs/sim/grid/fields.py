"""`Grid`: the nodal fields m^k, p^k, v^k, m^k_band of every fragment k, in the slot storage of `layout.py`.

A single-field grid (shared variants, or any run before its first latch) is dense slot 0 only. A
multi-field grid adds the owner word per node and a pool of rows for nodes that two or more
fragments reach, sized between frames from the rows the last frame used (`ensure_pool`). The
logical fields `mass`, `momentum`, `velocity`, `band_mass` ([K, X, Y, Z, …]) are rebuilt from the
slots for tests and small diagnostics; `fragment_mass` and `mixing` reduce the slots directly (torch
twins of `field_sums`, the two launches the per-frame diagnostics use). They
name a node's fragments from its claims, which the solver's "solo" particles skip (`SlotStorage.solo`):
read them from a grid filled with claims everywhere (the diagnostics' shadow grid, or solo off).
"""

from __future__ import annotations

import torch
import warp as wp

from ...errors import SimulationError
from ...runtime import ensure_warp, launch
from ..physics.contact import N_PAIR_STATS, N_STATS, NEVER, PAIR_FIRST_T, PAIR_FRAGMENTS, STAT_FIRST_T
from .domain import BYTES_PER_NODE, check_device_memory
from .field_metrics_kernels import OUT_ACTIVE, OUT_MASS, OUT_MIXING, OUT_SHARED, OUT_TOTAL, dense_sums, pool_sums
from .layout import EMPTY_KEY, OWNER_MASK, GridView, pool_capacity

SUM_ROWS = 256  # rows of `field_sums`' partial sums on a GPU


class Grid:
    """Slot storage on torch tensors, seen by the kernels through one `GridView` struct (`view`).

    `slots` = 1: one dense field. `slots` = S ≥ 2: up to S fields per node (sim.field_slots).
    `n_fields` (K, the number of fragment ids in use) sizes the logical fields and pair statistics."""

    def __init__(self, origin, dx: float, shape, device: str, slots: int = 1, max_fragments: int = 64):
        ensure_warp()
        self.origin = tuple(float(o) for o in origin)
        self.dx = float(dx)
        self.shape = tuple(int(s) for s in shape)
        if min(self.shape) < 5:
            raise SimulationError(f"sim.grid_shape {self.shape} is too small; every axis needs at least 5 nodes")
        self.device = device
        self.slots = int(slots)
        self.multi = self.slots > 1
        self.n_nodes = self.shape[0] * self.shape[1] * self.shape[2]
        check_device_memory(self.n_nodes * BYTES_PER_NODE * (2 if self.slots > 1 else 1), device, self.shape)
        self.n_fields = 1
        self.max_fragments = int(max_fragments)
        self.contact_stats = torch.zeros(N_STATS, dtype=torch.float32, device=device)
        self.contact_stats[STAT_FIRST_T] = NEVER
        # per-pair rows for the first PAIR_FRAGMENTS ids only: contact between higher ids counts in the totals
        # (max_fragments² rows would be 403 MB at 4,096 fragments, and the tracker reads them every frame)
        self.pair_fragments = min(self.max_fragments, PAIR_FRAGMENTS)
        self.pair_stats = torch.zeros(self.pair_fragments**2 * N_PAIR_STATS, dtype=torch.float32, device=device)
        self.pair_stats.view(-1, N_PAIR_STATS)[:, PAIR_FIRST_T] = NEVER
        self.wp = dict(stats=wp.from_torch(self.contact_stats), pair_stats=wp.from_torch(self.pair_stats))
        self.box = (0, 0, 0) + self.shape
        self.capacity = -1
        self._owner = torch.zeros(self.n_nodes if self.multi else 1, dtype=torch.int32, device=device)
        self.ensure_pool(0)

    # ---- buffers ------------------------------------------------------------------------------
    def ensure_pool(self, rows: int) -> bool:
        """A pool for about `rows` multi-fragment nodes (between frames only: buffers may move).
        Reallocated (zeroed) when too small or four times too large; returns whether it moved."""
        cap = pool_capacity(rows) if self.multi else 1
        if self.capacity >= cap and (not self.multi or self.capacity <= 4 * cap):
            return False
        self.capacity = cap
        extra = cap * (self.slots - 1)
        n = self.n_nodes + extra
        self._mp = torch.zeros((n, 4), dtype=torch.float32, device=self.device)
        self._vel = torch.zeros((n, 3), dtype=torch.float32, device=self.device)
        self.key = torch.full((cap,), EMPTY_KEY, dtype=torch.int32, device=self.device)
        self.pool_owner = torch.full((max(1, extra),), -1, dtype=torch.int32, device=self.device)
        self.band = torch.zeros(cap * self.slots, dtype=torch.float32, device=self.device)
        self._owner.zero_()
        self.mp = self._mp[: self.n_nodes].view(*self.shape, 4)
        self.vel = self._vel[: self.n_nodes].view(*self.shape, 3)
        v = GridView()
        v.mp = wp.from_torch(self._mp, dtype=wp.vec4)
        v.vel = wp.from_torch(self._vel, dtype=wp.vec3)
        v.owner = wp.from_torch(self._owner)
        v.key = wp.from_torch(self.key)
        v.pool_owner = wp.from_torch(self.pool_owner)
        v.band = wp.from_torch(self.band)
        v.shape = wp.vec3i(*self.shape)
        v.n_nodes = self.n_nodes
        v.slots = self.slots
        v.mask = cap - 1
        v.origin = wp.vec3(*self.origin)
        v.dx = self.dx
        v.inv_dx = 1.0 / self.dx
        self.view = v
        return True

    def rows_used(self) -> torch.Tensor:
        """Pool rows holding a node (a device count, read with the frame's other numbers)."""
        return (self.key >= 0).sum() if self.multi else torch.zeros((), dtype=torch.int64, device=self.device)

    def reset_claims(self) -> None:
        """Forget every claim (owner words, pool rows, pool slot owners): between frames, or when the
        routing changes."""
        if self.multi:
            self._owner.zero_()
            self.key.fill_(EMPTY_KEY)
            self.pool_owner.fill_(-1)
            self.band.zero_()
            self._mp[self.n_nodes :].zero_()  # a row claimed anew must start empty (clear_pool skips free rows)

    def clear(self) -> None:
        """Reset every accumulator (dense slot 0, owners, the pool)."""
        self._mp.zero_()
        self._owner.zero_()
        self.key.fill_(EMPTY_KEY)
        self.pool_owner.fill_(-1)
        self.band.zero_()

    def zero(self) -> None:
        """Reset accumulators and velocities (after a box change no stale node may survive)."""
        self.clear()
        self._vel.zero_()

    # ---- slot tables as torch (diagnostics and tests) -------------------------------------------
    def _slot0_fragment(self) -> torch.Tensor:  # [X·Y·Z] fragment in slot 0 (−1: none)
        if not self.multi:
            return torch.zeros(self.n_nodes, dtype=torch.int64, device=self.device)
        return (self._owner.long() & OWNER_MASK) - 1

    def _pool(self):
        """(nodes [R], pool fragment [R, S−1], pool buffer index [R, S−1], row index [R]) of used rows."""
        rows = torch.nonzero(self.key >= 0).flatten()
        s1 = self.slots - 1
        frag = self.pool_owner[: self.capacity * s1].view(self.capacity, s1)[rows].long()
        index = self.n_nodes + rows[:, None] * s1 + torch.arange(s1, device=self.device)[None, :]
        return self.key[rows].long(), frag, index, rows

    def _expand(self, dense: torch.Tensor, pooled: torch.Tensor) -> torch.Tensor:
        """Logical field [K, X·Y·Z, …] from slot values (dense [X·Y·Z, …], pooled [n − X·Y·Z, …])."""
        K = self.n_fields
        out = torch.zeros((K, self.n_nodes) + dense.shape[1:], dtype=dense.dtype, device=dense.device)
        f0 = self._slot0_fragment()
        ok = (f0 >= 0) & (f0 < K)
        out[f0[ok], torch.nonzero(ok).flatten()] = dense[ok]
        if self.multi:
            nodes, frag, index, _ = self._pool()
            ok = (frag >= 0) & (frag < K)
            vals = pooled[index - self.n_nodes]
            out.index_put_((frag[ok], nodes[:, None].expand_as(frag)[ok]), vals[ok], accumulate=True)
        return out

    def _logical(self, buf: torch.Tensor) -> torch.Tensor:
        return self._expand(buf[: self.n_nodes], buf[self.n_nodes :])

    @property
    def mass(self) -> torch.Tensor:  # [K, X, Y, Z]
        return self._logical(self._mp[:, 3]).view(self.n_fields, *self.shape)

    @property
    def momentum(self) -> torch.Tensor:  # [K, X, Y, Z, 3]
        return self._logical(self._mp[:, :3]).view(self.n_fields, *self.shape, 3)

    @property
    def velocity(self) -> torch.Tensor:  # [K, X, Y, Z, 3]
        return self._logical(self._vel).view(self.n_fields, *self.shape, 3)

    @property
    def band_mass(self) -> torch.Tensor:  # [K, X, Y, Z], kept only at nodes with a pool row
        K = self.n_fields
        out = torch.zeros((K, self.n_nodes), dtype=torch.float32, device=self.device)
        if self.multi:
            nodes, frag, _, rows = self._pool()
            band = self.band.view(self.capacity, self.slots)[rows]  # [R, S]
            f0 = self._slot0_fragment()[nodes]
            allf = torch.cat([f0[:, None], frag], 1)
            ok = (allf >= 0) & (allf < K)
            out.index_put_((allf[ok], nodes[:, None].expand_as(allf)[ok]), band[ok], accumulate=True)
        return out.view(K, *self.shape)

    def fragment_mass(self, K: int) -> torch.Tensor:
        """Σ_i m_i^k per fragment k < K, float64 [K], on the device (no host read); a single-field grid
        holds field 0 only."""
        m = self._mp[:, 3].double()
        out = torch.zeros(K, dtype=torch.float64, device=self.device)
        f0 = self._slot0_fragment()
        ok = (f0 >= 0) & (f0 < K)
        out.index_add_(0, f0.clamp(0, K - 1), torch.where(ok, m[: self.n_nodes], 0.0))
        if self.multi:
            frag, index, used = self._pool_all()
            ok = used[:, None] & (frag >= 0) & (frag < K)
            out.index_add_(0, frag.clamp(0, K - 1).reshape(-1), torch.where(ok, m[index], 0.0).reshape(-1))
        return out

    def _pool_all(self):
        """(pool fragment [C, S−1], buffer index [C, S−1], row used [C]) over every row (no host read)."""
        s1, C = self.slots - 1, self.capacity
        frag = self.pool_owner[: C * s1].view(C, s1).long()
        index = self.n_nodes + torch.arange(C * s1, device=self.device).view(C, s1)
        return frag, index, self.key >= 0

    def field_sums(self, eps_m: float, K: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(E_mix counterfactual, shared-support %, Σ_i m_i^k [K]) as `mixing` and `fragment_mass` give
        them, float64 on the device (no host read), from two Warp launches on the current Warp stream."""
        return self.field_sums_within(eps_m, K, (0, 0, 0) + self.shape)

    def field_sums_within(self, eps_m: float, K: int, box: tuple) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """`field_sums` of a grid whose slot 0 holds no mass outside the node box (x0, y0, z0, x1, y1, z1), [x0, x1)
        along x, …: the dense launch covers the box only. On the CPU the same numbers as `field_sums`, bit for
        bit (the box's nodes add in the same order, the nodes outside add nothing)."""
        if not self.multi:
            cf, shared = self.mixing(eps_m)
            return cf, shared, self.fragment_mass(K)
        rows = SUM_ROWS if self.device.startswith("cuda") else 1  # spread the atomics (see the kernels)
        out = torch.zeros((rows, OUT_MASS + K), dtype=torch.float64, device=self.device)
        o = wp.from_torch(out, dtype=wp.float64)
        lo, dims = wp.vec3i(*box[:3]), tuple(max(0, b - a) for a, b in zip(box[:3], box[3:]))
        if min(dims) > 0:
            launch(dense_sums, dims, [self.view, lo, float(eps_m), K, o], self.device)
        launch(pool_sums, self.capacity, [self.view, float(eps_m), K, o], self.device)
        out = out.sum(0)
        cf = _per_mass(out[OUT_MIXING], out[OUT_TOTAL])
        shared = 100.0 * out[OUT_SHARED] / out[OUT_ACTIVE].clamp_min(1.0)
        return cf, shared, out[OUT_MASS:]

    def mixing(self, eps_m: float) -> tuple[torch.Tensor, torch.Tensor]:
        """(E_mix counterfactual, shared-support %) of the stored fields (Eq. mixing), 0-d float64
        tensors on the device: at every node Σ_k m^k ‖v̄ − v^k‖² with v̄ = Σ_k p^k / Σ_k m^k, over Σ m;
        shared = nodes with ≥ 2 active fields over nodes with ≥ 1. Only pool rows can hold two fields."""
        m = self._mp[:, 3].double()
        zero = torch.zeros((), dtype=torch.float64, device=self.device)
        if not self.multi:
            return zero, zero
        p = self._mp[:, :3].double()
        frag, index, used = self._pool_all()
        nodes = self.key.long().clamp_min(0)
        on_pool = used[:, None] & (frag >= 0)  # a claimed slot of a used row: an unclaimed one holds no field
        mm = torch.cat([torch.where(used, m[nodes], 0.0)[:, None], torch.where(on_pool, m[index], 0.0)], 1)  # [C, S]
        total = m[: self.n_nodes].sum() + mm[:, 1:].sum()  # slot 0 and the claimed pool slots, as `pool_sums`
        pp = torch.cat(
            [torch.where(used[:, None], p[nodes], 0.0)[:, None], torch.where(on_pool[..., None], p[index], 0.0)], 1
        )  # [C, S, 3]
        on = mm > eps_m  # an active field has m > ε_m ≥ 0, so its row's M > 0: v̄ and v^k are exact at any mass
        M = mm.sum(1)  # [C]
        vbar = pp.sum(1) / torch.where(M > 0, M, 1.0)[:, None]
        v = torch.where(on[..., None], pp / torch.where(on, mm, 1.0)[..., None], torch.zeros_like(pp))
        cf = _per_mass((mm * on * ((vbar[:, None] - v) ** 2).sum(-1)).sum(), total)
        count = (m[: self.n_nodes] > eps_m).long()
        count.index_add_(0, nodes, torch.where(used, on[:, 1:].sum(1), 0))
        shared = 100.0 * (count >= 2).sum().double() / (count >= 1).sum().clamp_min(1).double()
        return cf, shared

    @property
    def nbytes(self) -> int:
        """Grid-buffer footprint (dense slot 0, owners and the pool, as allocated) in bytes."""
        ts = (self._mp, self._vel, self.key, self.pool_owner, self.band)
        owner = self._owner.numel() * 4 if self.multi else 0
        pool = sum(t.numel() * t.element_size() for t in ts[2:]) if self.multi else 0
        return sum(t.numel() * t.element_size() for t in ts[:2]) + owner + pool


def _per_mass(energy: torch.Tensor, total: torch.Tensor) -> torch.Tensor:
    """E_mix over the grid's total mass Σ m, 0 for an empty grid (no guard value that would bend a light grid's
    ratio: float32 masses are ≥ 1.4e-45 kg where they are not 0)."""
    return torch.where(total > 0, energy / torch.where(total > 0, total, 1.0), 0.0)
