"""P2G and G2P of the particles that are not solo, with one thread per (particle, stencil node).

Such a particle (another fragment within reach this frame) finds each of its 27 nodes' slots by a
hash-row lookup, and in P2G may claim them: 27 serial lookups per thread, while a solo particle's
27 deposits or loads are plain. On a GPU those threads finish long after the dense bulk; giving each
node its own thread makes every chain one node long (DESIGN.md "Performance rules").

P2G (Eq. multifield_p2g): thread t = 27 i + q deposits node q of the i-th listed particle,
m_i^k += w m_p,  p_i^k += w m_p (v_p + C_p(x_i − x_p)) − Δt V⁰ τ_p ∇w, with the same slot claims as
`kernels.p2g`'s loop. G2P (Eqs. field_g2p, field_apic, field_deformation): a warp of 32
threads per particle, lane q < 27 loads node q of the particle's own field and the warp sums
v = Σ w v_i, B = Σ w v_i (x_i − x_p)ᵀ and ∇v = Σ v_i ∇wᵀ by shuffles; lane 0 writes the particle.
On the CPU the lanes cannot cooperate, so lane 0 gathers all 27 nodes itself (`coop` = 0).
`order` lists the particles that are not solo first and `first[0]` counts them; the launches cover a
capacity ≥ first[0].
"""

from __future__ import annotations

import warp as wp

from ..clock import Clock, clock_dt
from ..stencil import atomic_add_vec4, deposit, finish_g2p, flat, node_terms_q, stencil, stencil_offset
from .kernels import deposit_index, gather_slot0, node_index, routed_field
from .layout import GridView

wp.set_module_options({"enable_backward": False})

LANES = 32  # threads per particle in `g2p_fanout`: one warp, lanes 27–31 add zeros

_LANE_SUM = r"""
#if defined(__CUDA_ARCH__)
    float s = a;
    for (int o = 16; o > 0; o >>= 1)
        s += __shfl_xor_sync(0xffffffffu, s, o);
    return s;
#else
    return a;
#endif
"""


@wp.func_native(_LANE_SUM)
def lane_sum(a: float) -> float:
    """Σ of `a` over the 32 lanes of the warp, in every lane (butterfly shuffles); `a` itself on the CPU.
    Every lane of the warp must call it."""
    ...


@wp.func
def lane_sum_vec3(a: wp.vec3):
    return wp.vec3(lane_sum(a[0]), lane_sum(a[1]), lane_sum(a[2]))


@wp.func
def lane_sum_mat33(a: wp.mat33):
    return wp.matrix_from_rows(lane_sum_vec3(a[0]), lane_sum_vec3(a[1]), lane_sum_vec3(a[2]))


@wp.kernel
def p2g_fanout(
    x: wp.array(dtype=wp.vec3),  # [N]
    v: wp.array(dtype=wp.vec3),  # [N]
    C: wp.array(dtype=wp.mat33),  # [N]
    mass: wp.array(dtype=float),  # [N]
    volume: wp.array(dtype=float),  # [N] rest volume V⁰
    stress: wp.array(dtype=wp.mat33),  # [N] Kirchhoff τ (band-released)
    fragment: wp.array(dtype=wp.int32),  # [N]
    band: wp.array(dtype=wp.int32),  # [N]
    order: wp.array(dtype=wp.int32),  # [N] the particles that are not solo first
    first: wp.array(dtype=wp.int32),  # [1] how many are not solo
    cache: wp.array(dtype=wp.int32),  # [27 × capacity] out: the buffer index each thread deposited into
    clock: Clock,  # Δt
    g: GridView,
    counts: wp.array(dtype=wp.int32),  # [N_COUNTS] (`p2g` counted the escapes)
):
    """Deposit node q = t mod 27 of the (t div 27)-th listed particle into its fragment's slot, and keep
    the slot's buffer index for G2P (the same index `read_index` finds: claims last the frame)."""
    t = wp.tid()
    i = t // 27
    if i >= first[0]:
        return
    p = order[i]
    k = routed_field(fragment[p], -1, 1)
    base, f = stencil_offset(x[p], g.origin, g.inv_dx, g.shape)
    weight, grad, dpos, o = node_terms_q(t - 27 * i, f, g.dx, g.inv_dx)
    n = flat(base + o, wp.vec3i(0, 0, 0), g.shape)
    m = mass[p]
    force = -clock_dt(clock) * volume[p] * stress[p]
    in_band = band[p]
    idx, row, s = deposit_index(g, n, k, in_band, counts)
    cache[t] = idx
    if in_band != 0 and row >= 0:
        wp.atomic_add(g.band, row * g.slots + s, weight * m)
    atomic_add_vec4(g.mp, idx, deposit(weight, grad, dpos, m, v[p], C[p], force))


@wp.kernel
def g2p_fanout(
    x: wp.array(dtype=wp.vec3),  # [N]
    v: wp.array(dtype=wp.vec3),  # [N]
    C: wp.array(dtype=wp.mat33),  # [N]
    F: wp.array(dtype=wp.mat33),  # [N]
    fragment: wp.array(dtype=wp.int32),  # [N]
    order: wp.array(dtype=wp.int32),  # [N] the particles that are not solo first
    first: wp.array(dtype=wp.int32),  # [1] how many are not solo
    cache: wp.array(dtype=wp.int32),  # [27 × capacity] P2G's buffer indices (with `cached`)
    cached: int,  # 1: this substep's P2G fanned out and filled `cache`
    coop: int,  # 1 (CUDA): the 32 lanes share the stencil; 0 (CPU): lane 0 gathers it alone
    clock: Clock,  # Δt
    g: GridView,
    lower: wp.vec3,  # particles are clamped into [lower, upper] and counted
    upper: wp.vec3,
    counts: wp.array(dtype=wp.int32),
    solo: wp.array(dtype=wp.int32),  # [N] (with `listed` > 0)
    listed: int,  # > 0: threads from `listed` on gather the solo particle t − listed from slot 0 (0: none)
):
    """Gather the (t div 32)-th listed particle from its own field, lane t mod 32 taking node lane < 27;
    with `listed` (= 32 × capacity) the same launch then gathers the solo particles, one thread each, so
    the listed particles' warps start first and the dense bulk fills the GPU behind them (one launch,
    no second kernel's gap and tail)."""
    t = wp.tid()
    if listed > 0 and t >= listed:
        p = t - listed
        if solo[p] == 0:
            return
        base, f, w, dw = stencil(x[p], g.origin, g.inv_dx, g.shape)
        vp, B, gradv = gather_slot0(g, base, f, w, dw)
        finish_g2p(p, vp, B, gradv, clock_dt(clock), g.inv_dx, x, v, C, F, lower, upper, counts)
        return
    i = t // LANES
    lane = t - LANES * i
    if i >= first[0]:
        return  # the whole warp: its 32 lanes share i
    if coop == 0 and lane != 0:
        return
    p = order[i]
    k = routed_field(fragment[p], -1, 1)
    base, f = stencil_offset(x[p], g.origin, g.inv_dx, g.shape)
    vp = wp.vec3(0.0)
    B = wp.mat33(0.0)
    gradv = wp.mat33(0.0)
    if coop != 0:
        if lane < 27:
            weight, grad, dpos, o = node_terms_q(lane, f, g.dx, g.inv_dx)
            vi = g.vel[node_index(g, base + o, k, cache, 27 * i + lane, cached)]
            vp = weight * vi
            B = weight * wp.outer(vi, dpos)
            gradv = wp.outer(vi, grad)
        vp = lane_sum_vec3(vp)  # every lane calls the shuffles
        B = lane_sum_mat33(B)
        gradv = lane_sum_mat33(gradv)
        if lane != 0:
            return
    else:
        for q in range(27):
            weight, grad, dpos, o = node_terms_q(q, f, g.dx, g.inv_dx)
            vi = g.vel[node_index(g, base + o, k, cache, 27 * i + q, cached)]
            vp = vp + weight * vi
            B = B + weight * wp.outer(vi, dpos)
            gradv = gradv + wp.outer(vi, grad)
    finish_g2p(p, vp, B, gradv, clock_dt(clock), g.inv_dx, x, v, C, F, lower, upper, counts)
