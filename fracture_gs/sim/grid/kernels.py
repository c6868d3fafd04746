"""Particle–grid transfer kernels of the slot storage: P2G, grid update (normalize, gravity, contact, boundaries)
and G2P — shared, fragment-conditioned (FractureFields, any number of fragments) and per-fragment passes.

The stencil math (B-spline weights, deposit, gather) is `sim/stencil.py`'s, shared with the per-fragment boxes.
Routing (Eqs. multifield_p2g, field_g2p): with `multifield` a particle writes to and reads from
the field of its own fragment k = o_p only, wherever the slot storage keeps it at that node
(`layout.py`); otherwise every particle uses the dense field. The float64 torch twins (dense
fields) are in `fracture_gs.sim.reference`.
"""

from __future__ import annotations

import warp as wp

from ..clock import Clock, clock_dt, clock_time
from ..physics.boundary import Colliders, apply_boundaries
from ..physics.contact import NORMAL_MASS_GRADIENT, contact_normal, contact_pair
from ..stencil import (
    atomic_add_vec4,
    deposit,
    finish_g2p,
    flat,
    gather,
    inside,
    node_terms,
    node_terms_q,
    normalized,
    stencil,
    unflat,
)
from ..storage import COUNT_ESCAPED, COUNT_POOL_OVERFLOW, COUNT_SLOT_OVERFLOW, MAX_SLOTS
from .layout import (
    EMPTY_KEY,
    OWNER_MASK,
    ROW_FLAG,
    GridView,
    claim_pool_slot,
    claim_row,
    claim_slot0,
    field_index,
    find_pool_slot,
    find_row,
)

wp.set_module_options({"enable_backward": False})  # forward-only kernels compile in half the time

mat_s3 = wp.types.matrix(shape=(MAX_SLOTS, 3), dtype=float)  # one vec3 per slot (registers of the pool pass)
vec_s = wp.types.vector(length=MAX_SLOTS, dtype=float)
vec_si = wp.types.vector(length=MAX_SLOTS, dtype=int)


@wp.func
def routed_field(o: int, only_fragment: int, multifield: int):
    """Field the particle writes to and reads from (its fragment under fragment-conditioned
    transfer, else the one shared field 0), or −1 when a per-fragment pass skips it."""
    if only_fragment >= 0 and o != only_fragment:
        return -1
    if multifield != 0 and o > 0:
        return o
    return 0


@wp.func
def deposit_index(g: GridView, n: int, k: int, in_band: int, counts: wp.array(dtype=wp.int32)):
    """(buffer index, pool row, slot) where fragment k deposits at node n: slot 0 if it owns it or
    claims it; else a pool slot of the node's row; else (slot overflow) slot 0 of another fragment.
    Band particles also make sure the node has a row, which holds the band mass the gate reads."""
    own = claim_slot0(g.owner, n, k)
    row = -1
    j = 0
    if own != k + 1 or in_band != 0:
        row = claim_row(g.key, g.owner, n, g.mask)
        if row < 0:
            wp.atomic_add(counts, COUNT_POOL_OVERFLOW, 1)
        elif own != k + 1:
            j = claim_pool_slot(g.pool_owner, row, g.slots, k)
            if j == 0:
                wp.atomic_add(counts, COUNT_SLOT_OVERFLOW, 1)
    return field_index(n, row, j, g.n_nodes, g.slots), row, j


@wp.func
def read_index(g: GridView, n: int, k: int):
    """Buffer index of fragment k's field at node n: the same slot P2G deposited into."""
    word = g.owner[n]
    if (word & OWNER_MASK) == k + 1 or (word & ROW_FLAG) == 0:
        return n
    row = find_row(g.key, n, g.mask)
    if row < 0:
        return n
    return field_index(n, row, find_pool_slot(g.pool_owner, row, g.slots, k), g.n_nodes, g.slots)


@wp.func
def node_index(g: GridView, node: wp.vec3i, k: int, cache: wp.array(dtype=wp.int32), c: int, cached: int):
    """Buffer index of fragment k's field at a stencil node: entry c of P2G's slot cache when this
    substep's P2G fanned out (`fanout_kernels.p2g_fanout`), else `read_index`'s lookup."""
    if cached != 0:
        return cache[c]
    return read_index(g, flat(node, wp.vec3i(0, 0, 0), g.shape), k)


@wp.func
def slot0_owned(g: GridView, base: wp.vec3i, k: int):
    """Fragment k already holds slot 0 at every node of the stencil (claimed earlier this frame), so
    P2G's deposits go to the dense slot: 27 independent loads (unrolled), no early exit."""
    owned = int(1)  # noqa: UP018 (a dynamic Warp variable)
    for i in range(3):  # the stencil's 3 × 3 × 3 owner words (a test for the fast path only)
        for j in range(3):
            for l in range(3):  # noqa: E741
                word = g.owner[flat(wp.vec3i(base[0] + i, base[1] + j, base[2] + l), wp.vec3i(0, 0, 0), g.shape)]
                if (word & OWNER_MASK) != k + 1:
                    owned = 0
    return owned != 0


@wp.func
def slot0_readable(g: GridView, base: wp.vec3i, k: int):
    """`read_index` gives slot 0 at every node of the stencil (fragment k's, or a node with no row)."""
    readable = int(1)  # noqa: UP018 (a dynamic Warp variable)
    for i in range(3):
        for j in range(3):
            for l in range(3):  # noqa: E741
                word = g.owner[flat(wp.vec3i(base[0] + i, base[1] + j, base[2] + l), wp.vec3i(0, 0, 0), g.shape)]
                if (word & OWNER_MASK) != k + 1 and (word & ROW_FLAG) != 0:
                    readable = 0
    return readable != 0


@wp.func
def launch_particle(
    t: int,
    n: int,
    solo: wp.array(dtype=wp.int32),
    order: wp.array(dtype=wp.int32),
    first: wp.array(dtype=wp.int32),
    split: int,
):
    """Particle of G2P's thread t, or −1. With `split` the launch has 2n threads: the first `first[0]`
    take the particles that are not solo (`order` lists them first), so their slot lookups, 27 serial
    hash probes each, start before the dense bulk and hide under it instead of finishing last; threads
    n … 2n−1 take the solo particles in their own order (coalesced, no indirection). Only G2P: in P2G
    the same order did not help and the extra threads only cost (docs/benchmarks/history-2026-11.md)."""
    if split == 0:
        return t
    if t < n:
        if t < first[0]:
            return order[t]
        return -1
    if solo[t - n] == 0:
        return -1
    return t - n


@wp.kernel
def p2g(
    x: wp.array(dtype=wp.vec3),  # [N]
    v: wp.array(dtype=wp.vec3),  # [N]
    C: wp.array(dtype=wp.mat33),  # [N]
    mass: wp.array(dtype=float),  # [N]
    volume: wp.array(dtype=float),  # [N] rest volume V⁰
    stress: wp.array(dtype=wp.mat33),  # [N] Kirchhoff τ (band-released)
    fragment: wp.array(dtype=wp.int32),  # [N] o_p (−1 before the first latch)
    band: wp.array(dtype=wp.int32),  # [N] γ_p
    solo: wp.array(dtype=wp.int32),  # [N] 1: no other fragment within reach this frame (dense slot 0, no claims)
    multifield: int,
    only_fragment: int,  # ≥ 0: skip every particle of another fragment (global fragment pass)
    fanout: int,  # 1: the particles that are not solo are left to `fanout_kernels.p2g_fanout`
    clock: Clock,  # Δt
    g: GridView,
    lo: wp.vec3i,  # active box [lo, hi): a stencil outside it is counted (the frame is redone)
    hi: wp.vec3i,
    counts: wp.array(dtype=wp.int32),  # [N_COUNTS] running counters
):
    """m_i^k += w m_p;  p_i^k += w m_p (v_p + C_p(x_i − x_p)) − Δt V⁰ τ_p ∇w  (k = routed field);
    band particles add w m_p to their slot's band mass at the node (Eq. band_mass)."""
    p = wp.tid()
    k = routed_field(fragment[p], only_fragment, multifield)
    if k < 0:
        return
    base, f, w, dw = stencil(x[p], g.origin, g.inv_dx, g.shape)
    if not (inside(base, lo, hi) and inside(base + wp.vec3i(2, 2, 2), lo, hi)):
        wp.atomic_add(counts, COUNT_ESCAPED, 1)  # the grid update will not see it: `advance` redoes the frame
    m = mass[p]
    vp = v[p]
    Cp = C[p]
    force = -clock_dt(clock) * volume[p] * stress[p]
    in_band = band[p]
    dense = multifield == 0 or solo[p] != 0
    if not dense and fanout != 0:
        return  # `fanout_kernels.p2g_fanout` deposits it, one thread per stencil node
    if not dense and in_band == 0:
        dense = slot0_owned(g, base, k)
    if dense:  # one field at every node reached, in slot 0: unrolled, one reduction per node
        for i in range(3):
            for j in range(3):
                for l in range(3):  # noqa: E741
                    weight, grad, dpos = node_terms(i, j, l, f, w, dw, g.dx, g.inv_dx)
                    n = flat(wp.vec3i(base[0] + i, base[1] + j, base[2] + l), wp.vec3i(0, 0, 0), g.shape)
                    atomic_add_vec4(g.mp, n, deposit(weight, grad, dpos, m, vp, Cp, force))
        return
    for q in range(27):  # kept as a loop: the slot claims inline once, not 27 times
        weight, grad, dpos, o = node_terms_q(q, f, g.dx, g.inv_dx)
        n = flat(base + o, wp.vec3i(0, 0, 0), g.shape)
        idx, row, s = deposit_index(g, n, k, in_band, counts)
        if in_band != 0 and row >= 0:
            wp.atomic_add(g.band, row * g.slots + s, weight * m)
        atomic_add_vec4(g.mp, idx, deposit(weight, grad, dpos, m, vp, Cp, force))


@wp.kernel
def clear_dense(g: GridView, box_origin: wp.vec3i):
    """Reset slot 0's accumulators over the active box (its owner stays claimed for the frame)."""
    ti, tj, tl = wp.tid()
    n = flat(wp.vec3i(ti + box_origin[0], tj + box_origin[1], tl + box_origin[2]), wp.vec3i(0, 0, 0), g.shape)
    g.mp[n] = wp.vec4(0.0)


@wp.kernel
def clear_pool(g: GridView):
    """Reset the pool slots' accumulators (rows and slot owners stay claimed for the frame)."""
    r = wp.tid()
    if g.key[r] == EMPTY_KEY:
        return
    for s in range(g.slots):
        g.band[r * g.slots + s] = 0.0
        if s > 0:
            g.mp[g.n_nodes + r * (g.slots - 1) + s - 1] = wp.vec4(0.0)


@wp.kernel
def grid_update_dense(
    g: GridView,
    box_origin: wp.vec3i,  # the launch covers the active box starting at this node
    multifield: int,
    eps_m: float,  # absolute ε_m
    clock: Clock,  # Δt and t
    gravity: wp.vec3,
    colliders: Colliders,
):
    """Slot 0 of every node without a pool row: v = p/m + Δt g where m > ε_m, else 0, then the
    boundaries. A node with a row is left to `grid_update_pool` whole (its slot 0 too: contact comes
    before the boundaries), so the two passes write disjoint nodes and may run at once."""
    ti, tj, tl = wp.tid()
    node = wp.vec3i(ti + box_origin[0], tj + box_origin[1], tl + box_origin[2])
    n = flat(node, wp.vec3i(0, 0, 0), g.shape)
    if multifield != 0:
        if (g.owner[n] & ROW_FLAG) != 0:
            return
    q = g.mp[n]
    v = normalized(q, eps_m, clock_dt(clock), gravity)
    if q[3] > eps_m:
        xi = g.origin + wp.vec3(float(node[0]), float(node[1]), float(node[2])) * g.dx
        v = apply_boundaries(v, node, xi, clock_time(clock), colliders)
    g.vel[n] = v


@wp.kernel
def grid_update_pool(
    g: GridView,
    eps_m: float,
    eps_b: float,  # absolute ε_band
    fill_mass: float,  # mass-gradient mode: two fields touch where m_a + m_b ≥ this [kg]
    gate: int,  # evaluate the contact gate (multi-field after a latch)
    project: int,  # apply the contact projection (FractureFields)
    normal_mode: int,  # contact.NORMAL_LATCHED or NORMAL_MASS_GRADIENT
    latched: wp.vec3,  # n_Π of the first event
    centroids: wp.array(dtype=wp.vec3),  # [K] fragment centroids (normal fallback)
    restitution: float,
    friction: float,  # Coulomb μ between fragments
    clock: Clock,  # Δt and t
    gravity: wp.vec3,
    colliders: Colliders,
    record: int,  # accumulate contact statistics (off when timing the transfer)
    stats: wp.array(dtype=float),  # [N_STATS]
    pair_stats: wp.array(dtype=float),  # [K·K·N_PAIR_STATS]
    n_fragments: int,  # K (pair rows of pair_stats)
    grad0: wp.array(dtype=wp.vec3),  # [capacity] ∇m of slot 0's field (mass-gradient normals)
):
    """Nodes with a pool row: every field normalized, the contact projection between every pair of
    active, approaching fields in contact (ordered by fragment id), then the boundaries. In contact:
    both band-supported (latched normal, the paper's gate), or together filling the node
    (m_a + m_b ≥ fill_mass, mass-gradient normals from the fields' nodal masses)."""
    r = wp.tid()
    n = g.key[r]
    if n == EMPTY_KEY:
        return
    dt = clock_dt(clock)
    t = clock_time(clock)
    node = unflat(n, g.shape)
    xi = g.origin + wp.vec3(float(node[0]), float(node[1]), float(node[2])) * g.dx
    V = mat_s3(0.0)
    G = mat_s3(0.0)
    m = vec_s(0.0)
    b = vec_s(0.0)
    frag = vec_si(-1)
    frag[0] = (g.owner[n] & OWNER_MASK) - 1
    q0 = g.mp[n]
    m[0] = q0[3]
    V[0] = normalized(q0, eps_m, dt, gravity)  # slot 0 too: `grid_update_dense` skips nodes with a row
    for s in range(g.slots):
        b[s] = g.band[r * g.slots + s]
        if s > 0:
            i = g.n_nodes + r * (g.slots - 1) + s - 1
            frag[s] = g.pool_owner[r * (g.slots - 1) + s - 1]
            q = g.mp[i]
            m[s] = q[3]
            V[s] = normalized(q, eps_m, dt, gravity)
    if gate != 0 and normal_mode == NORMAL_MASS_GRADIENT:  # ∇m of each field, from `pool_mass_gradients`
        G[0] = grad0[r]
        for s in range(1, g.slots):
            G[s] = g.vel[g.n_nodes + r * (g.slots - 1) + s - 1]
    if gate != 0:
        for a in range(g.slots):
            for c in range(a + 1, g.slots):
                touching = b[a] > eps_b and b[c] > eps_b
                if normal_mode == NORMAL_MASS_GRADIENT:
                    touching = m[a] + m[c] >= fill_mass
                if frag[a] >= 0 and frag[c] >= 0 and m[a] > eps_m and m[c] > eps_m and touching:
                    lo = a
                    hi = c
                    if frag[c] < frag[a]:
                        lo = c
                        hi = a
                    nrm = contact_normal(normal_mode, latched, G[lo], G[hi], centroids, frag[lo], frag[hi])
                    w0, w1 = contact_pair(
                        V[lo], V[hi], m[lo], m[hi], nrm, restitution, friction, project, record, stats, pair_stats,
                        frag[lo], frag[hi], n_fragments, t,
                    )  # fmt: skip
                    V[lo] = w0
                    V[hi] = w1
    for s in range(g.slots):
        v = V[s]
        if m[s] > eps_m:
            v = apply_boundaries(v, node, xi, t, colliders)
        if s == 0:
            g.vel[n] = v
        else:
            g.vel[g.n_nodes + r * (g.slots - 1) + s - 1] = v


@wp.func
def gather_slot0(g: GridView, base: wp.vec3i, f: wp.vec3, w: wp.mat33, dw: wp.mat33):
    """`gather` from slot 0 of the grid's fields."""
    return gather(g.vel, 0, g.shape, base, f, w, dw, g.dx, g.inv_dx)


@wp.kernel
def g2p(
    x: wp.array(dtype=wp.vec3),
    v: wp.array(dtype=wp.vec3),
    C: wp.array(dtype=wp.mat33),
    F: wp.array(dtype=wp.mat33),
    fragment: wp.array(dtype=wp.int32),
    solo: wp.array(dtype=wp.int32),  # [N] as in p2g
    order: wp.array(dtype=wp.int32),  # [N] the particles that are not solo first (read with split)
    first: wp.array(dtype=wp.int32),  # [1] how many are not solo
    split: int,  # 1: 2N threads, the particles that are not solo first (`launch_particle`)
    fanout: int,  # 1: the particles that are not solo are left to `fanout_kernels.g2p_fanout`
    cache: wp.array(dtype=wp.int32),  # [27 × capacity] P2G fan-out's buffer indices, by listed rank
    cached: int,  # 1 (with split): listed particles read their slots from `cache`, no lookups
    multifield: int,
    only_fragment: int,
    clock: Clock,  # Δt
    g: GridView,
    lower: wp.vec3,  # particles are clamped into [lower, upper] and counted
    upper: wp.vec3,
    counts: wp.array(dtype=wp.int32),
):
    """Eqs. field_g2p, field_apic, field_deformation from the particle's own field only (no fallback):
    v = Σ w v_i; C = 4/Δx² Σ w v_i (x_i − x_p)ᵀ; F ← (I + Δt Σ v_i ∇wᵀ) F; x ← x + Δt v."""
    t = wp.tid()
    p = launch_particle(t, x.shape[0], solo, order, first, split)
    if p < 0:
        return
    k = routed_field(fragment[p], only_fragment, multifield)
    if k < 0:
        return
    dense = multifield == 0 or solo[p] != 0
    if not dense and fanout != 0:
        return  # `fanout_kernels.g2p_fanout` gathers it, one thread per stencil node
    dt = clock_dt(clock)
    base, f, w, dw = stencil(x[p], g.origin, g.inv_dx, g.shape)
    vp = wp.vec3(0.0)
    B = wp.mat33(0.0)
    gradv = wp.mat33(0.0)
    use_cache = cached != 0 and split != 0 and t < x.shape[0]  # t: the particle's rank in `order`
    if not dense and not use_cache:
        dense = slot0_readable(g, base, k)
    if dense:  # every node's field of the particle in slot 0: the stencil unrolled
        vp, B, gradv = gather_slot0(g, base, f, w, dw)
    else:
        for q in range(27):  # kept as a loop: the slot lookup inlines once, not 27 times
            weight, grad, dpos, o = node_terms_q(q, f, g.dx, g.inv_dx)
            vi = g.vel[node_index(g, base + o, k, cache, 27 * t + q, wp.where(use_cache, 1, 0))]
            vp = vp + weight * vi
            B = B + weight * wp.outer(vi, dpos)
            gradv = gradv + wp.outer(vi, grad)
    finish_g2p(p, vp, B, gradv, dt, g.inv_dx, x, v, C, F, lower, upper, counts)
