"""Particle–grid transfer kernels: P2G, grid update (normalize, gravity, contact projection,
boundaries) and G2P — shared, fragment-conditioned (FractureFields) and per-fragment passes.

Quadratic B-spline weights with ξ = (x − origin)/Δx, base = ⌊ξ − 0.5⌋, f = ξ − base:
w = (½(1.5−f)², 0.75−(f−1)², ½(f−0.5)²), ∇w from dw = (f−1.5, −2(f−1), f−0.5)/Δx.
Routing (Eqs. multifield_p2g, field_g2p): with `multifield` a particle writes to and reads from
field k = o_p only; otherwise every particle uses field 0. Storage (see `grid.py`): field 1 sits in
slot 1 on the shared box S and in slot 0 elsewhere, where no fragment-0 particle reaches. The
float64 torch twins (dense fields) are in `fracture_gs.sim.reference`.
"""
from __future__ import annotations

import warp as wp

from .boundary import Colliders, apply_boundaries
from .layout import (STAT_DPX, STAT_DPY, STAT_DPZ, STAT_DVT, STAT_FIRST_T, STAT_GATED, STAT_PNORM, STAT_PROJECTED,
                     STAT_UN_AFTER, flat, inside, slot_index)

wp.set_module_options({"enable_backward": False})  # forward-only kernels compile in half the time



_RED_V4 = r"""
#if defined(__CUDA_ARCH__) && (__CUDA_ARCH__ >= 900)
    wp::vec4* p = &wp::index(arr, i);
    asm volatile("red.global.add.v4.f32 [%0], {%1, %2, %3, %4};"
                 :: "l"(p), "f"(value[0]), "f"(value[1]), "f"(value[2]), "f"(value[3]) : "memory");
#else
    wp::atomic_add(arr, i, value);
#endif
"""


@wp.func_native(_RED_V4)
def atomic_add_vec4(arr: wp.array(dtype=wp.vec4), i: int, value: wp.vec4):
    """arr[i,j,k,l] += value: one 16-byte vector reduction on Hopper (sm_90+), where P2G's
    (momentum, mass) scatter is bound by atomic throughput; Warp's atomic_add elsewhere."""
    ...


@wp.func
def stencil_base(xi: wp.vec3, shape: wp.vec3i):
    """Lowest stencil node ⌊ξ − 0.5⌋, clamped into the grid so a stray (or non-finite) particle
    never indexes outside it; the domain walls keep real particles well inside."""
    base = wp.vec3i(0, 0, 0)
    for a in range(3):
        b = wp.floor(xi[a] - 0.5)
        if not (b >= 0.0):  # also catches NaN
            b = 0.0
        if b > float(shape[a] - 3):
            b = float(shape[a] - 3)
        base[a] = int(b)
    return base


@wp.func
def stencil(xp: wp.vec3, origin: wp.vec3, inv_dx: float, shape: wp.vec3i):
    """Base node, weights w[a, axis] and their ξ-derivatives dw[a, axis] for a = 0, 1, 2."""
    xi = (xp - origin) * inv_dx
    base = stencil_base(xi, shape)
    f = xi - wp.vec3(float(base[0]), float(base[1]), float(base[2]))
    w = wp.mat33(0.0)
    dw = wp.mat33(0.0)
    for a in range(3):
        w[0, a] = 0.5 * (1.5 - f[a]) * (1.5 - f[a])
        w[1, a] = 0.75 - (f[a] - 1.0) * (f[a] - 1.0)
        w[2, a] = 0.5 * (f[a] - 0.5) * (f[a] - 0.5)
        dw[0, a] = f[a] - 1.5
        dw[1, a] = -2.0 * (f[a] - 1.0)
        dw[2, a] = f[a] - 0.5
    return base, f, w, dw


@wp.func
def node_terms(i: int, j: int, l: int, f: wp.vec3, w: wp.mat33, dw: wp.mat33, dx: float, inv_dx: float):
    """Weight w_ip, gradient ∇w_ip and offset x_i − x_p of stencil node (i, j, l)."""
    weight = w[i, 0] * w[j, 1] * w[l, 2]
    grad = wp.vec3(dw[i, 0] * w[j, 1] * w[l, 2], w[i, 0] * dw[j, 1] * w[l, 2], w[i, 0] * w[j, 1] * dw[l, 2]) * inv_dx
    dpos = (wp.vec3(float(i), float(j), float(l)) - f) * dx
    return weight, grad, dpos


@wp.func
def field_of(fragment: int, multifield: int):
    """Routing: field o_p under fragment-conditioned transfer, else the shared field 0."""
    if multifield != 0 and fragment > 0:
        return fragment
    return 0


@wp.func
def routed_field(o: int, only_fragment: int, multifield: int):
    """Field the particle writes to and reads from, or −1 when a per-fragment pass skips it."""
    if only_fragment >= 0 and o != only_fragment:
        return -1
    return field_of(o, multifield)


@wp.kernel
def p2g(
    x: wp.array(dtype=wp.vec3),  # [N]
    v: wp.array(dtype=wp.vec3),  # [N]
    C: wp.array(dtype=wp.mat33),  # [N]
    mass: wp.array(dtype=float),  # [N]
    volume: wp.array(dtype=float),  # [N] rest volume V⁰
    stress: wp.array(dtype=wp.mat33),  # [N] Kirchhoff τ (band-released)
    fragment: wp.array(dtype=wp.int32),  # [N] o_p (−1 before the latch)
    band: wp.array(dtype=wp.int32),  # [N] γ_p
    multifield: int,
    only_fragment: int,  # ≥ 0: skip every particle of another fragment (global fragment pass)
    dt: float,
    origin: wp.vec3,
    dx: float,
    inv_dx: float,
    shape: wp.vec3i,
    s_lo: wp.vec3i,  # shared box S = [s_lo, s_hi) of slot 1 (empty: one field)
    s_hi: wp.vec3i,
    lo0: wp.vec3i,  # box of field 0 (or of the single field) ...
    hi0: wp.vec3i,
    lo1: wp.vec3i,  # ... and of field 1; a stencil outside its field's box is counted
    hi1: wp.vec3i,
    grid_mp: wp.array(dtype=wp.vec4),  # [X·Y·Z + |S|] (p, m) packed: slot 0, then slot 1
    grid_mb: wp.array(dtype=float),  # [2·|S|] band mass of fields 0 and 1 on S
    escaped: wp.array(dtype=wp.int32),  # [1] running count of stencils outside their box
):
    """m_i^k += w m_p;  p_i^k += w m_p (v_p + C_p(x_i − x_p)) − Δt V⁰ τ_p ∇w  (k = routed field);
    band particles add w m_p to m_band,i^k on S (Eq. band_mass), the only place it is read."""
    p = wp.tid()
    k = routed_field(fragment[p], only_fragment, multifield)
    if k < 0:
        return
    base, f, w, dw = stencil(x[p], origin, inv_dx, shape)
    lo = wp.where(k == 1, lo1, lo0)
    hi = wp.where(k == 1, hi1, hi0)
    if not (inside(base, lo, hi) and inside(base + wp.vec3i(2, 2, 2), lo, hi)):
        wp.atomic_add(escaped, 0, 1)  # the grid update will not see it: `advance` redoes the frame
    m = mass[p]
    vp = v[p]
    Cp = C[p]
    force = -dt * volume[p] * stress[p]
    in_band = band[p] != 0
    s_dims = s_hi - s_lo
    band_offset = k * s_dims[0] * s_dims[1] * s_dims[2]
    for i in range(3):
        for j in range(3):
            for l in range(3):
                weight, grad, dpos = node_terms(i, j, l, f, w, dw, dx, inv_dx)
                node = wp.vec3i(base[0] + i, base[1] + j, base[2] + l)
                mom = weight * m * (vp + Cp * dpos) + force * grad
                atomic_add_vec4(grid_mp, slot_index(node, k, shape, s_lo, s_hi), wp.vec4(mom[0], mom[1], mom[2], weight * m))
                if in_band and inside(node, s_lo, s_hi):
                    wp.atomic_add(grid_mb, band_offset + flat(node, s_lo, s_dims), weight * m)


@wp.kernel
def clear_fields(
    box_origin: wp.vec3i,  # launch over the active box starting here
    shape: wp.vec3i,
    s_lo: wp.vec3i,
    s_hi: wp.vec3i,
    grid_mp: wp.array(dtype=wp.vec4),
    grid_mb: wp.array(dtype=float),
):
    """Reset slot 0 over the active box and slot 1 and band mass on S, in one launch."""
    ti, tj, tl = wp.tid()
    node = wp.vec3i(ti + box_origin[0], tj + box_origin[1], tl + box_origin[2])
    grid_mp[slot_index(node, 0, shape, s_lo, s_hi)] = wp.vec4(0.0)
    if inside(node, s_lo, s_hi):
        grid_mp[slot_index(node, 1, shape, s_lo, s_hi)] = wp.vec4(0.0)
        s_dims = s_hi - s_lo
        s = flat(node, s_lo, s_dims)
        grid_mb[s] = 0.0
        grid_mb[s_dims[0] * s_dims[1] * s_dims[2] + s] = 0.0


@wp.func
def normalized(q: wp.vec4, eps_m: float, dt: float, gravity: wp.vec3):
    """v = p/m + Δt g for an active field (m > ε_m), else 0."""
    if q[3] > eps_m:
        return wp.vec3(q[0], q[1], q[2]) / q[3] + dt * gravity
    return wp.vec3(0.0)


@wp.func
def contact_projection(v0: wp.vec3, v1: wp.vec3, m0: float, m1: float, n: wp.vec3, e: float):
    """Eqs. impulse, contact_update: J_n = −(1+e)u_n / (1/m⁰ + 1/m¹) for approaching fields
    (u_n = (v¹ − v⁰)·n < 0); equal and opposite, so m⁰v⁰ + m¹v¹ is unchanged."""
    un = wp.dot(v1 - v0, n)
    if un >= 0.0:
        return v0, v1
    J = -(1.0 + e) * un / (1.0 / m0 + 1.0 / m1)
    return v0 - (J / m0) * n, v1 + (J / m1) * n


@wp.func
def record_contact(stats: wp.array(dtype=float), t: float, v0: wp.vec3, v1: wp.vec3, w0: wp.vec3, w1: wp.vec3,
                   m0: float, m1: float, normal: wp.vec3, project: int):
    """Contact diagnostics of one gated node: count, first time, node momentum change, residual
    approach speed and change of tangential relative velocity."""
    wp.atomic_add(stats, STAT_GATED, 1.0)
    wp.atomic_min(stats, STAT_FIRST_T, t)
    if project != 0:
        wp.atomic_add(stats, STAT_PROJECTED, 1.0)
    before = m0 * v0 + m1 * v1
    dp = (m0 * w0 + m1 * w1) - before
    wp.atomic_add(stats, STAT_DPX, dp[0])
    wp.atomic_add(stats, STAT_DPY, dp[1])
    wp.atomic_add(stats, STAT_DPZ, dp[2])
    wp.atomic_add(stats, STAT_PNORM, wp.length(before))
    wp.atomic_max(stats, STAT_UN_AFTER, wp.max(0.0, -wp.dot(w1 - w0, normal)))
    rel_t_before = (v1 - v0) - wp.dot(v1 - v0, normal) * normal
    rel_t_after = (w1 - w0) - wp.dot(w1 - w0, normal) * normal
    wp.atomic_max(stats, STAT_DVT, wp.length(rel_t_after - rel_t_before))


@wp.kernel
def grid_update(
    box_origin: wp.vec3i,  # the launch covers the active box starting at this node
    shape: wp.vec3i,
    s_lo: wp.vec3i,  # shared box S of slot 1 (empty: one field)
    s_hi: wp.vec3i,
    grid_mp: wp.array(dtype=wp.vec4),  # [X·Y·Z + |S|]
    grid_mb: wp.array(dtype=float),  # [2·|S|]
    grid_v: wp.array(dtype=wp.vec3),  # out [X·Y·Z + |S|]
    eps_m: float,  # absolute ε_m
    eps_b: float,  # absolute ε_band
    gate: int,  # evaluate the contact gate (multi-field after the latch)
    project: int,  # apply the contact projection (FractureFields)
    normal: wp.vec3,  # n_Π
    restitution: float,
    dt: float,
    gravity: wp.vec3,
    origin: wp.vec3,
    dx: float,
    t: float,
    colliders: Colliders,
    record: int,  # accumulate the contact statistics (diagnostics; off when timing the transfer)
    stats: wp.array(dtype=float),  # [N_STATS] contact statistics (accumulated)
):
    """Per node and field: v^k = p^k/m^k + Δt g where m^k > ε_m, else 0; on S, the contact
    projection where both fields are active, band-supported and approaching; then boundaries."""
    ti, tj, tl = wp.tid()
    node = wp.vec3i(ti + box_origin[0], tj + box_origin[1], tl + box_origin[2])
    i0 = slot_index(node, 0, shape, s_lo, s_hi)
    q0 = grid_mp[i0]
    v0 = normalized(q0, eps_m, dt, gravity)
    xi = origin + wp.vec3(float(node[0]), float(node[1]), float(node[2])) * dx
    if inside(node, s_lo, s_hi):
        i1 = slot_index(node, 1, shape, s_lo, s_hi)
        q1 = grid_mp[i1]
        v1 = normalized(q1, eps_m, dt, gravity)
        m0 = q0[3]
        m1 = q1[3]
        if gate != 0 and m0 > eps_m and m1 > eps_m:
            s_dims = s_hi - s_lo
            s = flat(node, s_lo, s_dims)
            if grid_mb[s] > eps_b and grid_mb[s_dims[0] * s_dims[1] * s_dims[2] + s] > eps_b:
                if wp.dot(v1 - v0, normal) < 0.0:
                    w0 = v0
                    w1 = v1
                    if project != 0:
                        w0, w1 = contact_projection(v0, v1, m0, m1, normal, restitution)
                    if record != 0:
                        record_contact(stats, t, v0, v1, w0, w1, m0, m1, normal, project)
                    v0 = w0
                    v1 = w1
        if m1 > eps_m:
            v1 = apply_boundaries(v1, node, xi, t, colliders)
        grid_v[i1] = v1
    if q0[3] > eps_m:
        v0 = apply_boundaries(v0, node, xi, t, colliders)
    grid_v[i0] = v0


@wp.kernel
def g2p(
    x: wp.array(dtype=wp.vec3),
    v: wp.array(dtype=wp.vec3),
    C: wp.array(dtype=wp.mat33),
    F: wp.array(dtype=wp.mat33),
    fragment: wp.array(dtype=wp.int32),
    multifield: int,
    only_fragment: int,
    dt: float,
    origin: wp.vec3,
    dx: float,
    inv_dx: float,
    shape: wp.vec3i,
    s_lo: wp.vec3i,
    s_hi: wp.vec3i,
    grid_v: wp.array(dtype=wp.vec3),  # [X·Y·Z + |S|]
    lower: wp.vec3,  # particles are clamped into [lower, upper] and counted
    upper: wp.vec3,
    clamped: wp.array(dtype=wp.int32),  # [1] running count
):
    """Eqs. field_g2p, field_apic, field_deformation from field o_p only (no fallback):
    v = Σ w v_i; C = 4/Δx² Σ w v_i (x_i − x_p)ᵀ; F ← (I + Δt Σ v_i ∇wᵀ) F; x ← x + Δt v."""
    p = wp.tid()
    k = routed_field(fragment[p], only_fragment, multifield)
    if k < 0:
        return
    base, f, w, dw = stencil(x[p], origin, inv_dx, shape)
    vp = wp.vec3(0.0)
    B = wp.mat33(0.0)
    gradv = wp.mat33(0.0)
    for i in range(3):
        for j in range(3):
            for l in range(3):
                weight, grad, dpos = node_terms(i, j, l, f, w, dw, dx, inv_dx)
                vi = grid_v[slot_index(wp.vec3i(base[0] + i, base[1] + j, base[2] + l), k, shape, s_lo, s_hi)]
                vp = vp + weight * vi
                B = B + weight * wp.outer(vi, dpos)
                gradv = gradv + wp.outer(vi, grad)
    v[p] = vp
    C[p] = B * (4.0 * inv_dx * inv_dx)
    F[p] = (wp.identity(n=3, dtype=float) + dt * gradv) * F[p]
    xn = x[p] + dt * vp
    xc = wp.vec3(wp.clamp(xn[0], lower[0], upper[0]), wp.clamp(xn[1], lower[1], upper[1]), wp.clamp(xn[2], lower[2], upper[2]))
    if xc[0] != xn[0] or xc[1] != xn[1] or xc[2] != xn[2]:
        wp.atomic_add(clamped, 0, 1)
    x[p] = xc
