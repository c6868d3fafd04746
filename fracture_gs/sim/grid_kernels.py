"""Grid-side kernels of a transfer substep: the reset of the fields' accumulators and the grid update
(normalize, gravity, contact between the fields at a node, boundaries), each one launch over the active
box's nodes and the pool's rows together.

Grid update: v_i^k = p_i^k / m_i^k + Δt g where m_i^k > ε_m (else 0); at a node with a pool row (two or
more fields) the approach-only contact projection between every pair of fields in contact (Eqs.
contact_gate, contact_projection; `contact.py`), then the boundaries (`boundary.py`). A launch's first
threads take the pool rows (every slot of the row's node, slot 0 too), the rest the box's nodes without a
row, so every node is one thread's and the slow rows start first; on the CPU the same functions run in
the same order per node, so trajectories are bitwise those of separate passes.
"""

from __future__ import annotations

import warp as wp

from .boundary import Colliders, apply_boundaries
from .clock import Clock, clock_dt, clock_time
from .contact import NORMAL_MASS_GRADIENT, contact_normal, contact_projection, record_contact
from .layout import EMPTY_KEY, MAX_SLOTS, OWNER_MASK, ROW_FLAG, GridView, flat, unflat

wp.set_module_options({"enable_backward": False})

mat_s3 = wp.types.matrix(shape=(MAX_SLOTS, 3), dtype=float)  # one vec3 per slot (registers of a pool row)
vec_s = wp.types.vector(length=MAX_SLOTS, dtype=float)
vec_si = wp.types.vector(length=MAX_SLOTS, dtype=int)


@wp.func
def box_node(t: int, box_origin: wp.vec3i, box_dims: wp.vec3i):
    """Flat index of the box's t-th node (row-major over the box)."""
    c = unflat(t, box_dims)
    return wp.vec3i(c[0] + box_origin[0], c[1] + box_origin[1], c[2] + box_origin[2])


@wp.kernel
def clear_fields(g: GridView, box_origin: wp.vec3i, box_dims: wp.vec3i, rows: int):
    """Reset the accumulators: threads t < `rows` those of pool row t (band masses, slots 1…S−1; a free
    row is skipped), the rest slot 0 over the active box. Owners and rows stay claimed for the frame."""
    t = wp.tid()
    if t < rows:
        if g.key[t] == EMPTY_KEY:
            return
        for s in range(g.slots):
            g.band[t * g.slots + s] = 0.0
            if s > 0:
                g.mp[g.n_nodes + t * (g.slots - 1) + s - 1] = wp.vec4(0.0)
        return
    g.mp[flat(box_node(t - rows, box_origin, box_dims), wp.vec3i(0, 0, 0), g.shape)] = wp.vec4(0.0)


@wp.func
def normalized(q: wp.vec4, eps_m: float, dt: float, gravity: wp.vec3):
    """v = p/m + Δt g for an active field (m > ε_m), else 0."""
    if q[3] > eps_m:
        return wp.vec3(q[0], q[1], q[2]) / q[3] + dt * gravity
    return wp.vec3(0.0)


@wp.func
def update_row(
    r: int,
    g: GridView,
    eps_m: float,
    eps_b: float,
    fill_mass: float,
    gate: int,
    project: int,
    normal_mode: int,
    latched: wp.vec3,
    centroids: wp.array(dtype=wp.vec3),
    restitution: float,
    friction: float,
    dt: float,
    t: float,
    gravity: wp.vec3,
    colliders: Colliders,
    record: int,
    stats: wp.array(dtype=float),
    pair_stats: wp.array(dtype=float),
    n_fragments: int,
    grad0: wp.array(dtype=wp.vec3),
):
    """Pool row r's node: every field normalized, the contact projection between every pair of active,
    approaching fields in contact (ordered by fragment id), then the boundaries. In contact: both
    band-supported (latched normal, the paper's gate), or together filling the node (m_a + m_b ≥
    fill_mass, mass-gradient normals from the fields' nodal masses)."""
    n = g.key[r]
    if n == EMPTY_KEY:
        return
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
    V[0] = normalized(q0, eps_m, dt, gravity)  # slot 0 too: its node is this thread's alone
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
                    nrm = contact_normal(normal_mode, latched, G[lo], G[hi], centroids[frag[lo]], centroids[frag[hi]])
                    v0 = V[lo]
                    v1 = V[hi]
                    if wp.dot(v1 - v0, nrm) < 0.0:
                        w0 = v0
                        w1 = v1
                        if project != 0:
                            w0, w1 = contact_projection(v0, v1, m[lo], m[hi], nrm, restitution, friction)
                        if record != 0:
                            pair = -1
                            if frag[hi] < n_fragments:
                                pair = frag[lo] * n_fragments + frag[hi]
                            record_contact(stats, pair_stats, pair, t, v0, v1, w0, w1, m[lo], m[hi], nrm, project)
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
def update_slot0(
    g: GridView,
    node: wp.vec3i,
    multifield: int,
    eps_m: float,
    dt: float,
    t: float,
    gravity: wp.vec3,
    colliders: Colliders,
):
    """Slot 0 of a node without a pool row: v = p/m + Δt g where m > ε_m, else 0, then the boundaries (a
    node with a row is its pool row's thread's)."""
    n = flat(node, wp.vec3i(0, 0, 0), g.shape)
    if multifield != 0:
        if (g.owner[n] & ROW_FLAG) != 0:
            return
    q = g.mp[n]
    v = normalized(q, eps_m, dt, gravity)
    if q[3] > eps_m:
        xi = g.origin + wp.vec3(float(node[0]), float(node[1]), float(node[2])) * g.dx
        v = apply_boundaries(v, node, xi, t, colliders)
    g.vel[n] = v


@wp.kernel
def grid_update(
    g: GridView,
    box_origin: wp.vec3i,  # the active box: its first node and its size in nodes
    box_dims: wp.vec3i,
    rows: int,  # pool rows in the launch (the pool's capacity on a multi-field grid, else 0)
    multifield: int,
    eps_m: float,  # absolute ε_m
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
    grad0: wp.array(dtype=wp.vec3),  # [capacity] ∇m of slot 0's field (`normal_kernels`, mass-gradient normals)
):
    """Threads t < `rows`: pool row t (`update_row`); the rest: the box's nodes without a row (`update_slot0`)."""
    i = wp.tid()
    dt = clock_dt(clock)
    t = clock_time(clock)
    if i < rows:
        update_row(
            i, g, eps_m, eps_b, fill_mass, gate, project, normal_mode, latched, centroids, restitution, friction,
            dt, t, gravity, colliders, record, stats, pair_stats, n_fragments, grad0,
        )  # fmt: skip
        return
    update_slot0(g, box_node(i - rows, box_origin, box_dims), multifield, eps_m, dt, t, gravity, colliders)
