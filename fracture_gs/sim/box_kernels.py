"""Fields in dense boxes, one per fragment (docs/DESIGN.md "Grid storage: per-fragment boxes").

Fragment k's field lives on the nodes of its own box B_k: lo_k + [0, dims_k), stored at
offset_k + (i·dims_y + j)·dims_z + l of one buffer for all boxes. Every particle takes the dense path into
its own fragment's box: no owner words, claims or pool. Launches cover the buffer's capacity; an index past
the boxes has box_of = −1.

- `box_band_mass`: each field's band mass (its band particles' Σ w_ip m_p), for the latched normals' gate.
- `box_p2g_runs`: Eq. multifield_p2g, m_i^k += Σ w_ip m_p, p_i^k += Σ w_ip m_p (v_p + C_p(x_i − x_p)) − Δt V⁰ τ_p
  ∇w_ip, for the particles of fragment k into B_k, `run` consecutive particles a thread (a stencil that
  leaves B_k is counted as an escape and not deposited: the frame is then redone with larger boxes).
- `box_grid_update`: per field node v_i^k = p_i^k / m_i^k + Δt g where m_i^k > ε_m (else 0), then the
  boundaries; where two or more fields hold mass at a node, each links its field to the next one there
  (`next`), the thread of the lowest fragment id lists the node, and `box_contact` (few threads, packed)
  follows the node's chain: it normalizes every field there, projects every pair
  in fragment order (the Gauss–Seidel of `contact.contact_projection`; normals and gate of
  `contact.contact_normal`: the fields' mass gradients, central differences inside each box, with
  m_a + m_b ≥ fill_mass, or the latched normal with both band masses > ε_b), then applies the boundaries to
  every field there. Only the boxes that overlap a node's own box are searched (`over`, made per fit).
  Fields beyond the first `slots` at a node keep their own velocity (no contact) and are counted.
- `box_g2p`: Eqs. field_g2p / field_apic / field_deformation from the particle's own box; threads past the
  particles clear every field for the next P2G (m, p, the band mass, the contact list): no launch of its own.
Twins: `reference.p2g`, `reference.grid_update`, `reference.contact_fields`, `reference.g2p` on K dense
fields (tests/test_fragment_boxes.py).
"""

from __future__ import annotations

import warp as wp

from .boundary import Colliders, apply_boundaries
from .clock import Clock, clock_dt, clock_time
from .contact import NORMAL_MASS_GRADIENT, contact_normal, contact_pair
from .layout import COUNT_ESCAPED, COUNT_SLOT_OVERFLOW, MAX_SLOTS
from .run_kernels import stencil_sums
from .transfer_kernels import atomic_add_vec4, deposit, finish_g2p, gather, node_terms, normalized, stencil

wp.set_module_options({"enable_backward": False})

MAX_FIELDS = MAX_SLOTS  # most fields one node's contact couples (sim.field_slots ≤ this)
vec_fi = wp.types.vector(length=MAX_FIELDS, dtype=wp.int32)
vec_f = wp.types.vector(length=MAX_FIELDS, dtype=float)
mat_f3 = wp.types.matrix(shape=(MAX_FIELDS, 3), dtype=float)
band_sums = wp.types.vector(length=27, dtype=float)  # band mass of the 27 stencil nodes


@wp.struct
class BoxView:
    """Every fragment's box (`boxes.FragmentBoxes.view`)."""

    lo: wp.array(dtype=wp.vec3i)  # [K_max] lowest node of box k
    dims: wp.array(dtype=wp.vec3i)  # [K_max] nodes per axis
    offset: wp.array(dtype=wp.int32)  # [K_max + 1] first buffer index of box k
    box_of: wp.array(dtype=wp.int32)  # [capacity] the box a buffer index belongs to (−1: none)
    over_start: wp.array(dtype=wp.int32)  # [K_max + 1] box k's overlapping boxes: over[over_start[k]:over_start[k+1]]
    over: wp.array(dtype=wp.int32)  # [K_max²] ascending fragment ids
    over_lo: wp.array(dtype=wp.vec3i)  # [K_max²] lo, dims and offset of the box over[o] (no dependent loads)
    over_dims: wp.array(dtype=wp.vec3i)
    over_off: wp.array(dtype=wp.int32)
    mp: wp.array(dtype=wp.vec4)  # [capacity] (momentum, mass)
    vel: wp.array(dtype=wp.vec3)  # [capacity]
    band: wp.array(dtype=float)  # [capacity] the field's band-particle mass (the latched normals' gate)
    leaders: wp.array(dtype=wp.int32)  # [1 + capacity] how many nodes need contact, then their leaders' indices
    next: wp.array(dtype=wp.int32)  # [capacity] the next field with mass at the node, in fragment order (−1: none)
    origin: wp.vec3
    dx: float
    inv_dx: float
    shape: wp.vec3i  # the grid's nodes per axis (stencils are clamped into it, as on the dense grid)
    boxes: int  # K in use


@wp.func
def box_index(b: BoxView, k: int, node: wp.vec3i):
    """Buffer index of `node` in box k, or −1 outside it."""
    d = b.dims[k]
    r = node - b.lo[k]
    if r[0] < 0 or r[1] < 0 or r[2] < 0 or r[0] >= d[0] or r[1] >= d[1] or r[2] >= d[2]:
        return -1
    return b.offset[k] + (r[0] * d[1] + r[1]) * d[2] + r[2]


@wp.func
def partner_index(b: BoxView, o: int, node: wp.vec3i):
    """Buffer index of `node` in the overlapping box of entry o of the overlap lists, or −1 outside it."""
    d = b.over_dims[o]
    r = node - b.over_lo[o]
    if r[0] < 0 or r[1] < 0 or r[2] < 0 or r[0] >= d[0] or r[1] >= d[1] or r[2] >= d[2]:
        return -1
    return b.over_off[o] + (r[0] * d[1] + r[1]) * d[2] + r[2]


@wp.func
def stencil_inside(b: BoxView, k: int, base: wp.vec3i):
    """All 27 nodes of the stencil at `base` lie in box k."""
    return box_index(b, k, base) >= 0 and box_index(b, k, base + wp.vec3i(2, 2, 2)) >= 0


@wp.func
def clear_node(b: BoxView, t: int, band: int):
    """Node t's (m, p) (and band mass) to 0 for the next P2G; the first also empties the contact list."""
    b.mp[t] = wp.vec4(0.0)
    if band != 0:
        b.band[t] = 0.0
    if t == 0:
        b.leaders[0] = 0


@wp.kernel
def box_p2g_runs(
    x: wp.array(dtype=wp.vec3),  # [N]
    v: wp.array(dtype=wp.vec3),  # [N]
    C: wp.array(dtype=wp.mat33),  # [N]
    mass: wp.array(dtype=float),  # [N]
    volume: wp.array(dtype=float),  # [N] rest volume V⁰
    stress: wp.array(dtype=wp.mat33),  # [N] Kirchhoff τ
    fragment: wp.array(dtype=wp.int32),  # [N] the particle's box
    clock: Clock,  # Δt
    b: BoxView,
    run: int,  # consecutive particles per thread
    counts: wp.array(dtype=wp.int32),  # [N_COUNTS]
):
    """Deposits of `run` consecutive particles a thread (`run_kernels.p2g_runs` on boxes): those with the same
    fragment and stencil base are summed in registers and reach their box as one reduction per node (run = 1:
    one particle a thread)."""
    t = wp.tid()
    dt = clock_dt(clock)
    acc = stencil_sums()
    cur = wp.vec3i(-1, -1, -1)
    ck = int(-1)  # noqa: UP018 (a dynamic Warp variable)
    for p in range(t * run, wp.min(t * run + run, x.shape[0])):
        k = wp.max(fragment[p], 0)
        base, f, w, dw = stencil(x[p], b.origin, b.inv_dx, b.shape)
        if not stencil_inside(b, k, base):
            wp.atomic_add(counts, COUNT_ESCAPED, 1)
            continue
        if k != ck or base[0] != cur[0] or base[1] != cur[1] or base[2] != cur[2]:
            if ck >= 0:
                flush_box(b, ck, cur, acc)
            acc = stencil_sums()
            cur = base
            ck = k
        m = mass[p]
        vp = v[p]
        Cp = C[p]
        force = -dt * volume[p] * stress[p]
        for i in range(3):
            for j in range(3):
                for l in range(3):  # noqa: E741
                    q = 9 * i + 3 * j + l
                    weight, grad, dpos = node_terms(i, j, l, f, w, dw, b.dx, b.inv_dx)
                    dep = deposit(weight, grad, dpos, m, vp, Cp, force)
                    for c in range(4):
                        acc[q, c] = acc[q, c] + dep[c]
    if ck >= 0:
        flush_box(b, ck, cur, acc)


@wp.func
def flush_box(b: BoxView, k: int, base: wp.vec3i, acc: stencil_sums):
    """Add a run's 27 node sums to box k: one reduction per node."""
    origin = box_index(b, k, base)
    d = b.dims[k]
    for i in range(3):
        for j in range(3):
            for l in range(3):  # noqa: E741
                q = 9 * i + 3 * j + l
                atomic_add_vec4(
                    b.mp, origin + (i * d[1] + j) * d[2] + l, wp.vec4(acc[q, 0], acc[q, 1], acc[q, 2], acc[q, 3])
                )


@wp.kernel
def box_band_mass(
    x: wp.array(dtype=wp.vec3),  # [N]
    mass: wp.array(dtype=float),  # [N]
    fragment: wp.array(dtype=wp.int32),  # [N]
    band: wp.array(dtype=wp.int32),  # [N] γ_p ≠ 0: an interface-band particle
    b: BoxView,
    run: int,  # consecutive particles per thread
):
    """The band mass of every field, Σ w_ip m_p over its band particles (the latched normals' contact gate), in
    a pass of its own so that P2G carries no band work: `run` consecutive particles a thread, summed in
    registers while they share fragment and stencil base."""
    t = wp.tid()
    acc = band_sums()
    cur = wp.vec3i(-1, -1, -1)
    ck = int(-1)  # noqa: UP018 (a dynamic Warp variable)
    for p in range(t * run, wp.min(t * run + run, x.shape[0])):
        if band[p] == 0:
            continue
        k = wp.max(fragment[p], 0)
        base, f, w, dw = stencil(x[p], b.origin, b.inv_dx, b.shape)
        if not stencil_inside(b, k, base):
            continue  # counted by P2G
        if k != ck or base[0] != cur[0] or base[1] != cur[1] or base[2] != cur[2]:
            if ck >= 0:
                flush_band(b, ck, cur, acc)
            acc = band_sums()
            cur = base
            ck = k
        m = mass[p]
        for i in range(3):
            for j in range(3):
                for l in range(3):  # noqa: E741
                    q = 9 * i + 3 * j + l
                    acc[q] = acc[q] + w[i, 0] * w[j, 1] * w[l, 2] * m
    if ck >= 0:
        flush_band(b, ck, cur, acc)


@wp.func
def flush_band(b: BoxView, k: int, base: wp.vec3i, acc: band_sums):
    origin = box_index(b, k, base)
    d = b.dims[k]
    for i in range(3):
        for j in range(3):
            for l in range(3):  # noqa: E741
                wp.atomic_add(b.band, origin + (i * d[1] + j) * d[2] + l, acc[9 * i + 3 * j + l])


@wp.func
def node_mass(b: BoxView, i: int, step: int, r: int, extent: int):
    """Mass at buffer index i + step, whose coordinate along its axis is r (0 outside [0, extent))."""
    if r < 0 or r >= extent:
        return 0.0
    return b.mp[i + step][3]


@wp.func
def box_mass_gradient(b: BoxView, k: int, i: int, node: wp.vec3i):
    """∇m^k at the node of buffer index i in box k, by central differences of the box's nodal masses (0 beyond
    the box) [kg/m]."""
    d = b.dims[k]
    r = node - b.lo[k]
    sx = d[1] * d[2]
    h = 0.5 * b.inv_dx
    gx = node_mass(b, i, sx, r[0] + 1, d[0]) - node_mass(b, i, -sx, r[0] - 1, d[0])
    gy = node_mass(b, i, d[2], r[1] + 1, d[1]) - node_mass(b, i, -d[2], r[1] - 1, d[1])
    gz = node_mass(b, i, 1, r[2] + 1, d[2]) - node_mass(b, i, -1, r[2] - 1, d[2])
    return wp.vec3(gx, gy, gz) * h


@wp.func
def buffer_node(b: BoxView, k: int, t: int):
    """Grid node of buffer index t in box k."""
    d = b.dims[k]
    r = t - b.offset[k]
    return b.lo[k] + wp.vec3i(r // (d[1] * d[2]), (r // d[2]) % d[1], r % d[2])


@wp.func
def node_position(b: BoxView, node: wp.vec3i):
    return b.origin + wp.vec3(float(node[0]), float(node[1]), float(node[2])) * b.dx


@wp.kernel
def box_grid_update(b: BoxView, eps_m: float, clock: Clock, gravity: wp.vec3, colliders: Colliders):
    """One thread per buffer index with mass: it links its field to the next field with mass at its node (in
    fragment order, `next`); a field alone there gets v = p/m + Δt g and the boundaries; where fields meet,
    the lowest fragment's thread lists the node for `box_contact` and the others leave it."""
    t = wp.tid()
    k = b.box_of[t]
    if k < 0:
        return
    q = b.mp[t]
    if q[3] <= eps_m:
        b.vel[t] = wp.vec3(0.0)
        return
    node = buffer_node(b, k, t)
    lower = int(0)  # noqa: UP018 (a dynamic Warp variable)
    succ = int(-1)  # noqa: UP018
    for o in range(b.over_start[k], b.over_start[k + 1]):  # ascending: the lower fragments come first
        i = partner_index(b, o, node)
        if i >= 0:
            if b.mp[i][3] > eps_m:
                if b.over[o] < k:
                    lower = 1
                else:
                    succ = i
                    break
    b.next[t] = succ
    if lower != 0:
        return  # a lower fragment has mass here: it leads
    if succ >= 0:
        b.leaders[1 + wp.atomic_add(b.leaders, 0, 1)] = t
        return
    v = normalized(q, eps_m, clock_dt(clock), gravity)
    b.vel[t] = apply_boundaries(v, node, node_position(b, node), clock_time(clock), colliders)


@wp.kernel
def box_contact(
    b: BoxView,
    eps_m: float,
    eps_b: float,  # latched normals: two fields touch where both band masses exceed this [kg]
    fill_mass: float,  # mass-gradient normals: two fields touch where m_a + m_b ≥ this [kg]
    normal_mode: int,  # contact.NORMAL_LATCHED or NORMAL_MASS_GRADIENT
    latched: wp.vec3,  # n_Π of the first event (the mass-gradient normals' last fallback)
    centroids: wp.array(dtype=wp.vec3),  # [K] fragment centroids (normal fallback)
    restitution: float,
    friction: float,
    project: int,  # apply the projection (FractureFields; 0: Local Multi-Field, detection only)
    record: int,  # accumulate the contact statistics
    slots: int,  # fields a node's contact couples; more are counted as slot overflows
    clock: Clock,  # Δt and t
    gravity: wp.vec3,
    colliders: Colliders,
    stats: wp.array(dtype=float),  # [N_STATS]
    pair_stats: wp.array(dtype=float),  # [K·K·N_PAIR_STATS]
    n_fragments: int,  # K (pair rows of pair_stats)
    counts: wp.array(dtype=wp.int32),
    stride: int,  # listed nodes per sweep of the launch: working thread s takes the nodes s, s + stride, ...
    lanes: int,  # threads per listed node, of which only the first works (the others spread the nodes over warps)
):
    """The nodes `box_grid_update` listed, packed into few threads, each following its node's chain of fields
    (`next`): normalization of every field there, the pairwise projection in fragment order, then the
    boundaries (as the slot storage's pool pass). Fields past the first `slots` keep their own velocity."""
    dt = clock_dt(clock)
    time = clock_time(clock)
    tid = wp.tid()
    if tid % lanes != 0:
        return
    for e in range(tid / lanes, b.leaders[0], stride):
        t = b.leaders[1 + e]
        node = buffer_node(b, b.box_of[t], t)
        xi = node_position(b, node)
        # the node's fields in fragment order, loaded once (the sweep then runs on these copies)
        idx = vec_fi(-1)
        frag = vec_fi(0)
        m = vec_f(0.0)
        band = vec_f(0.0)
        V = mat_f3(0.0)
        n = int(0)  # noqa: UP018 (a dynamic Warp variable)
        i = t
        while i >= 0:
            if n < slots:
                idx[n] = i
                n += 1
            else:  # kept, uncoupled: its own velocity and the boundaries only
                wp.atomic_add(counts, COUNT_SLOT_OVERFLOW, 1)
                b.vel[i] = apply_boundaries(normalized(b.mp[i], eps_m, dt, gravity), node, xi, time, colliders)
            i = b.next[i]
        G = mat_f3(0.0)
        for a in range(n):
            ia = idx[a]
            q = b.mp[ia]
            frag[a] = b.box_of[ia]
            m[a] = q[3]
            band[a] = b.band[ia]
            V[a] = normalized(q, eps_m, dt, gravity)
            if normal_mode == NORMAL_MASS_GRADIENT:
                G[a] = box_mass_gradient(b, frag[a], ia, node)
        for a in range(n):
            for c in range(a + 1, n):
                touching = m[a] + m[c] >= fill_mass
                if normal_mode != NORMAL_MASS_GRADIENT:
                    touching = band[a] > eps_b and band[c] > eps_b
                if touching:
                    nrm = contact_normal(normal_mode, latched, G[a], G[c], centroids[frag[a]], centroids[frag[c]])
                    w0, w1 = contact_pair(
                        V[a], V[c], m[a], m[c], nrm, restitution, friction, project, record, stats, pair_stats,
                        frag[a], frag[c], n_fragments, time,
                    )  # fmt: skip
                    V[a] = w0
                    V[c] = w1
            b.vel[idx[a]] = apply_boundaries(V[a], node, xi, time, colliders)


@wp.kernel
def box_g2p(
    x: wp.array(dtype=wp.vec3),
    v: wp.array(dtype=wp.vec3),
    C: wp.array(dtype=wp.mat33),
    F: wp.array(dtype=wp.mat33),
    fragment: wp.array(dtype=wp.int32),
    clock: Clock,  # Δt
    b: BoxView,
    lower: wp.vec3,  # particles are clamped into [lower, upper] and counted
    upper: wp.vec3,
    counts: wp.array(dtype=wp.int32),
    clear: int,  # threads past the particles clear the boxes for the next P2G (G2P reads only velocities)
    band: int,  # with `clear`: the band masses too
):
    p = wp.tid()
    if p >= x.shape[0]:
        if clear != 0:
            clear_node(b, p - x.shape[0], band)
        return
    k = wp.max(fragment[p], 0)
    base, f, w, dw = stencil(x[p], b.origin, b.inv_dx, b.shape)
    if not stencil_inside(b, k, base):
        return  # counted by P2G
    vp, B, gradv = gather(b.vel, b.offset[k], b.dims[k], base - b.lo[k], f, w, dw, b.dx, b.inv_dx)
    finish_g2p(p, vp, B, gradv, clock_dt(clock), b.inv_dx, x, v, C, F, lower, upper, counts)
