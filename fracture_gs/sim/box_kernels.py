"""Fields in dense boxes, one per fragment (docs/DESIGN.md "Grid storage: per-fragment boxes (plan)").

Fragment k's field lives on the nodes of its own box B_k: lo_k + [0, dims_k), stored at
offset_k + (i·dims_y + j)·dims_z + l of one buffer for all boxes. Every particle takes the dense path into
its own fragment's box: no owner words, claims or pool, and no limit on how many fields meet at a node.

- `box_p2g_runs`: Eq. multifield_p2g, m_i^k += Σ w_ip m_p, p_i^k += Σ w_ip m_p (v_p + C_p(x_i − x_p)) − Δt V⁰ τ_p
  ∇w_ip, for the particles of fragment k into B_k, `run` consecutive particles a thread (a stencil that
  leaves B_k is counted, as an escape from the active box is, and not deposited: the caller fits the boxes
  so that it cannot happen).
- `box_normalize`: v_i^k = p_i^k / m_i^k + Δt g where m_i^k > ε_m, else 0.
- `box_gradients`: ∇m of every field with mass, by central differences inside its box (0 beyond it).
- `box_contact`: at a node where two or more fields hold mass, the thread of the lowest fragment id there
  projects every pair in fragment order (the Gauss–Seidel of `contact.contact_projection`), the other
  fields' threads leaving that node to it. Normals and gate as the slot storage's (`contact.contact_normal`):
  the fields' mass gradients and m_a + m_b ≥ fill_mass, or the latched normal and both band masses > ε_b.
- `box_boundaries`: the grid-side boundaries on every field, after the contact (as the slot storage's
  pool pass orders them).
- `box_g2p`: Eqs. field_g2p / field_apic / field_deformation from the particle's own box.
Twins: `reference.p2g`, `reference.grid_update`, `reference.contact_fields`, `reference.g2p` on K dense
fields (tests/test_fragment_boxes.py).
"""

from __future__ import annotations

import warp as wp

from .boundary import Colliders, apply_boundaries
from .contact import NORMAL_MASS_GRADIENT, contact_normal, contact_pair
from .layout import COUNT_ESCAPED, COUNT_SLOT_OVERFLOW
from .run_kernels import stencil_sums
from .transfer_kernels import atomic_add_vec4, deposit, finish_g2p, gather, node_terms, normalized, stencil

wp.set_module_options({"enable_backward": False})

MAX_FIELDS = 8  # fields one contact thread projects at a node; more are counted as slot overflows
vec_f = wp.types.vector(length=MAX_FIELDS, dtype=float)
vec_fi = wp.types.vector(length=MAX_FIELDS, dtype=wp.int32)
mat_f3 = wp.types.matrix(shape=(MAX_FIELDS, 3), dtype=float)


@wp.struct
class BoxView:
    """Every fragment's box (`boxes.FragmentBoxes.view`)."""

    lo: wp.array(dtype=wp.vec3i)  # [K] lowest node of box k
    dims: wp.array(dtype=wp.vec3i)  # [K] nodes per axis
    offset: wp.array(dtype=wp.int32)  # [K + 1] first buffer index of box k; offset[K] = all nodes
    box_of: wp.array(dtype=wp.int32)  # [nodes] the box a buffer index belongs to
    mp: wp.array(dtype=wp.vec4)  # [nodes] (momentum, mass)
    vel: wp.array(dtype=wp.vec3)  # [nodes]
    grad: wp.array(dtype=wp.vec3)  # [nodes] ∇m of the node's field (`box_gradients`)
    band: wp.array(dtype=float)  # [nodes] the field's band-particle mass (the latched normals' gate)
    origin: wp.vec3
    dx: float
    inv_dx: float
    shape: wp.vec3i  # the grid's nodes per axis (stencils are clamped into it, as on the dense grid)
    boxes: int  # K


@wp.func
def box_index(b: BoxView, k: int, node: wp.vec3i):
    """Buffer index of `node` in box k, or −1 outside it."""
    d = b.dims[k]
    r = node - b.lo[k]
    if r[0] < 0 or r[1] < 0 or r[2] < 0 or r[0] >= d[0] or r[1] >= d[1] or r[2] >= d[2]:
        return -1
    return b.offset[k] + (r[0] * d[1] + r[1]) * d[2] + r[2]


@wp.func
def box_mass(b: BoxView, k: int, node: wp.vec3i):
    i = box_index(b, k, node)
    if i < 0:
        return 0.0
    return b.mp[i][3]


@wp.func
def stencil_inside(b: BoxView, k: int, base: wp.vec3i):
    """All 27 nodes of the stencil at `base` lie in box k."""
    return box_index(b, k, base) >= 0 and box_index(b, k, base + wp.vec3i(2, 2, 2)) >= 0


@wp.kernel
def box_p2g_runs(
    x: wp.array(dtype=wp.vec3),  # [N]
    v: wp.array(dtype=wp.vec3),  # [N]
    C: wp.array(dtype=wp.mat33),  # [N]
    mass: wp.array(dtype=float),  # [N]
    volume: wp.array(dtype=float),  # [N] rest volume V⁰
    stress: wp.array(dtype=wp.mat33),  # [N] Kirchhoff τ
    fragment: wp.array(dtype=wp.int32),  # [N] the particle's box
    band: wp.array(dtype=wp.int32),  # [N] γ_p ≠ 0: its mass also goes to the field's band mass
    dt: float,
    b: BoxView,
    run: int,  # consecutive particles per thread
    counts: wp.array(dtype=wp.int32),  # [N_COUNTS]
):
    """Deposits of `run` consecutive particles a thread (`run_kernels.p2g_runs` on boxes): those with the same
    fragment and stencil base are summed in registers and reach their box as one reduction per node (run = 1:
    one particle a thread)."""
    t = wp.tid()
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
        in_band = band[p] != 0
        origin = box_index(b, k, base)
        d = b.dims[k]
        for i in range(3):
            for j in range(3):
                for l in range(3):  # noqa: E741
                    q = 9 * i + 3 * j + l
                    weight, grad, dpos = node_terms(i, j, l, f, w, dw, b.dx, b.inv_dx)
                    dep = deposit(weight, grad, dpos, m, vp, Cp, force)
                    for c in range(4):
                        acc[q, c] = acc[q, c] + dep[c]
                    if in_band:  # few particles (the band around a cut): straight to the node
                        wp.atomic_add(b.band, origin + (i * d[1] + j) * d[2] + l, weight * m)
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
def box_normalize(b: BoxView, eps_m: float, dt: float, gravity: wp.vec3):
    t = wp.tid()
    b.vel[t] = normalized(b.mp[t], eps_m, dt, gravity)


@wp.func
def box_node(b: BoxView, i: int):
    """(fragment, grid node) of buffer index i."""
    k = b.box_of[i]
    d = b.dims[k]
    r = i - b.offset[k]
    return k, b.lo[k] + wp.vec3i(r // (d[1] * d[2]), (r // d[2]) % d[1], r % d[2])


@wp.kernel
def box_boundaries(b: BoxView, eps_m: float, t: float, colliders: Colliders):
    """The grid-side boundaries (`boundary.apply_boundaries`) on every field with mass, after the contact."""
    i = wp.tid()
    if b.mp[i][3] > eps_m:
        k, node = box_node(b, i)
        xi = b.origin + wp.vec3(float(node[0]), float(node[1]), float(node[2])) * b.dx
        b.vel[i] = apply_boundaries(b.vel[i], node, xi, t, colliders)


@wp.func
def box_mass_gradient(b: BoxView, k: int, node: wp.vec3i):
    """∇m^k at `node` by central differences of box k's nodal masses (0 beyond the box) [kg/m]."""
    out = wp.vec3(0.0)
    for a in range(3):
        e = wp.vec3i(0, 0, 0)
        e[a] = 1
        out[a] = (box_mass(b, k, node + e) - box_mass(b, k, node - e)) * (0.5 * b.inv_dx)
    return out


@wp.kernel
def box_gradients(b: BoxView, eps_m: float):
    """∇m of every field with mass at its node, a thread per box node: the contact leaders then read it
    instead of making six lookups per field in series."""
    t = wp.tid()
    G = wp.vec3(0.0)
    if b.mp[t][3] > eps_m:
        k, node = box_node(b, t)
        G = box_mass_gradient(b, k, node)
    b.grad[t] = G


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
    time: float,  # of the substep [s] (the first contact's)
    stats: wp.array(dtype=float),  # [N_STATS]
    pair_stats: wp.array(dtype=float),  # [K·K·N_PAIR_STATS]
    n_fragments: int,  # K (pair rows of pair_stats)
    counts: wp.array(dtype=wp.int32),
):
    """One thread per box node; the lowest fragment with mass at a node projects its approaching pairs (as the
    slot storage's pool pass: the same gate, normal, projection and statistics per pair)."""
    t = wp.tid()
    if b.mp[t][3] <= eps_m:
        return
    k, node = box_node(b, t)
    for j in range(k):
        if box_mass(b, j, node) > eps_m:
            return  # a lower fragment has mass here: its thread leads
    idx = vec_fi(-1)
    frag = vec_fi(-1)
    m = vec_f(0.0)
    V = mat_f3(0.0)
    n = int(0)  # noqa: UP018 (a dynamic Warp variable)
    for j in range(k, b.boxes):
        i = box_index(b, j, node)
        if i >= 0:
            mj = b.mp[i][3]
            if mj > eps_m:
                if n < MAX_FIELDS:
                    idx[n] = i
                    frag[n] = j
                    m[n] = mj
                    V[n] = b.vel[i]
                    n += 1
                else:
                    wp.atomic_add(counts, COUNT_SLOT_OVERFLOW, 1)
    if n < 2:
        return
    G = mat_f3(0.0)
    for a in range(n):
        G[a] = b.grad[idx[a]]
    for a in range(n):
        for c in range(a + 1, n):
            touching = m[a] + m[c] >= fill_mass
            if normal_mode != NORMAL_MASS_GRADIENT:
                touching = b.band[idx[a]] > eps_b and b.band[idx[c]] > eps_b
            if touching:
                nrm = contact_normal(normal_mode, latched, G[a], G[c], centroids[frag[a]], centroids[frag[c]])
                w0, w1 = contact_pair(
                    V[a], V[c], m[a], m[c], nrm, restitution, friction, project, record, stats, pair_stats,
                    frag[a], frag[c], n_fragments, time,
                )  # fmt: skip
                V[a] = w0
                V[c] = w1
    for a in range(n):
        b.vel[idx[a]] = V[a]


@wp.kernel
def box_g2p(
    x: wp.array(dtype=wp.vec3),
    v: wp.array(dtype=wp.vec3),
    C: wp.array(dtype=wp.mat33),
    F: wp.array(dtype=wp.mat33),
    fragment: wp.array(dtype=wp.int32),
    dt: float,
    b: BoxView,
    lower: wp.vec3,  # particles are clamped into [lower, upper] and counted
    upper: wp.vec3,
    counts: wp.array(dtype=wp.int32),
):
    p = wp.tid()
    k = wp.max(fragment[p], 0)
    base, f, w, dw = stencil(x[p], b.origin, b.inv_dx, b.shape)
    if not stencil_inside(b, k, base):
        return  # counted by P2G
    vp, B, gradv = gather(b.vel, b.offset[k], b.dims[k], base - b.lo[k], f, w, dw, b.dx, b.inv_dx)
    finish_g2p(p, vp, B, gradv, dt, b.inv_dx, x, v, C, F, lower, upper, counts)
