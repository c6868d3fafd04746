"""The MLS-MPM stencil math every grid storage shares (`grid/`: the slot storage, `boxes/`: the per-fragment boxes,
`diff/`: the differentiable solver): quadratic B-spline weights, a particle's deposit at a node, the gather of a dense
field, the grid update's normalization and the end of G2P. Warp compiles a `@wp.func` into the module of each kernel
that calls it, so the kernels that use these are the same code wherever the functions live.

Quadratic B-spline weights with ξ = (x − origin)/Δx, base = ⌊ξ − 0.5⌋, f = ξ − base:
w = (½(1.5−f)², 0.75−(f−1)², ½(f−0.5)²), ∇w from dw = (f−1.5, −2(f−1), f−0.5)/Δx.
Node indices: a node box (lo, dims) is flattened row-major, (i·dims_y + j)·dims_z + l (`flat`). The float64 torch
twins are in `fracture_gs.sim.reference`.
"""

from __future__ import annotations

import warp as wp

from .storage import COUNT_CLAMPED

wp.set_module_options({"enable_backward": False})  # forward-only kernels compile in half the time


@wp.func
def inside(node: wp.vec3i, lo: wp.vec3i, hi: wp.vec3i):
    return (
        node[0] >= lo[0]
        and node[0] < hi[0]
        and node[1] >= lo[1]
        and node[1] < hi[1]
        and node[2] >= lo[2]
        and node[2] < hi[2]
    )


@wp.func
def flat(node: wp.vec3i, lo: wp.vec3i, dims: wp.vec3i):
    d = node - lo
    return (d[0] * dims[1] + d[1]) * dims[2] + d[2]


@wp.func
def unflat(n: int, shape: wp.vec3i):
    return wp.vec3i(n // (shape[1] * shape[2]), (n // shape[2]) % shape[1], n % shape[2])


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
def stencil_offset(xp: wp.vec3, origin: wp.vec3, inv_dx: float, shape: wp.vec3i):
    """Base node and fractional offset f = ξ − base of a particle at xp."""
    xi = (xp - origin) * inv_dx
    base = stencil_base(xi, shape)
    return base, xi - wp.vec3(float(base[0]), float(base[1]), float(base[2]))


@wp.func
def stencil(xp: wp.vec3, origin: wp.vec3, inv_dx: float, shape: wp.vec3i):
    """Base node, weights w[a, axis] and their ξ-derivatives dw[a, axis] for a = 0, 1, 2."""
    base, f = stencil_offset(xp, origin, inv_dx, shape)
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
def axis_terms(i: int, f: float):
    """Quadratic B-spline weight and its ξ-derivative of stencil offset i ∈ {0, 1, 2} along one axis,
    by arithmetic selection (no indexing: a runtime i must not push the stencil into local memory)."""
    w0 = 0.5 * (1.5 - f) * (1.5 - f)
    w1 = 0.75 - (f - 1.0) * (f - 1.0)
    w2 = 0.5 * (f - 0.5) * (f - 0.5)
    w = wp.where(i == 0, w0, wp.where(i == 1, w1, w2))
    d = wp.where(i == 0, f - 1.5, wp.where(i == 1, -2.0 * (f - 1.0), f - 0.5))
    return w, d


@wp.func
def node_terms_q(q: int, f: wp.vec3, dx: float, inv_dx: float):
    """`node_terms` of stencil node q = 9i + 3j + l, for a loop that is not unrolled (same float ops)."""
    i = q // 9
    j = (q // 3) % 3
    l = q % 3  # noqa: E741
    wx, dwx = axis_terms(i, f[0])
    wy, dwy = axis_terms(j, f[1])
    wz, dwz = axis_terms(l, f[2])
    weight = wx * wy * wz
    grad = wp.vec3(dwx * wy * wz, wx * dwy * wz, wx * wy * dwz) * inv_dx
    dpos = (wp.vec3(float(i), float(j), float(l)) - f) * dx
    return weight, grad, dpos, wp.vec3i(i, j, l)


@wp.func
def deposit(weight: float, grad: wp.vec3, dpos: wp.vec3, m: float, vp: wp.vec3, Cp: wp.mat33, force: wp.mat33):
    """What particle p adds at node i (Eq. multifield_p2g): (w m_p (v_p + C_p(x_i − x_p)) − Δt V⁰ τ_p ∇w, w m_p),
    with force = −Δt V⁰ τ_p."""
    mom = weight * m * (vp + Cp * dpos) + force * grad
    return wp.vec4(mom[0], mom[1], mom[2], weight * m)


stencil_sums = wp.types.matrix(shape=(27, 4), dtype=float)  # (momentum, mass) of the 27 stencil nodes


@wp.func
def add_particle(
    acc: stencil_sums, f: wp.vec3, w: wp.mat33, dw: wp.mat33, dx: float, inv_dx: float, m: float, vp: wp.vec3,
    Cp: wp.mat33, force: wp.mat33,
):  # fmt: skip
    """`acc` plus one particle's 27 deposits (`deposit`: mass m, velocity vp, affine Cp, stress
    term force = −Δt V⁰ τ), the sums a run keeps in registers."""
    out = acc
    for i in range(3):
        for j in range(3):
            for l in range(3):  # noqa: E741
                q = 9 * i + 3 * j + l
                weight, grad, dpos = node_terms(i, j, l, f, w, dw, dx, inv_dx)
                d = deposit(weight, grad, dpos, m, vp, Cp, force)
                for c in range(4):
                    out[q, c] = out[q, c] + d[c]
    return out


@wp.func
def normalized(q: wp.vec4, eps_m: float, dt: float, gravity: wp.vec3):
    """v = p/m + Δt g for an active field (m > ε_m), else 0."""
    if q[3] > eps_m:
        return wp.vec3(q[0], q[1], q[2]) / q[3] + dt * gravity
    return wp.vec3(0.0)


@wp.func
def finish_g2p(
    p: int,
    vp: wp.vec3,
    B: wp.mat33,
    gradv: wp.mat33,
    dt: float,
    inv_dx: float,
    x: wp.array(dtype=wp.vec3),
    v: wp.array(dtype=wp.vec3),
    C: wp.array(dtype=wp.mat33),
    F: wp.array(dtype=wp.mat33),
    lower: wp.vec3,
    upper: wp.vec3,
    counts: wp.array(dtype=wp.int32),
):
    """Write particle p's gathered v, C = 4/Δx² B, F ← (I + Δt ∇v) F and x ← x + Δt v (clamped, counted)."""
    v[p] = vp
    C[p] = B * (4.0 * inv_dx * inv_dx)
    F[p] = (wp.identity(n=3, dtype=float) + dt * gradv) * F[p]
    xn = x[p] + dt * vp
    xc = wp.vec3(
        wp.clamp(xn[0], lower[0], upper[0]), wp.clamp(xn[1], lower[1], upper[1]), wp.clamp(xn[2], lower[2], upper[2])
    )
    if xc[0] != xn[0] or xc[1] != xn[1] or xc[2] != xn[2]:
        wp.atomic_add(counts, COUNT_CLAMPED, 1)
    x[p] = xc


@wp.func
def gather(
    vel: wp.array(dtype=wp.vec3),
    off: int,
    shape: wp.vec3i,
    base: wp.vec3i,
    f: wp.vec3,
    w: wp.mat33,
    dw: wp.mat33,
    dx: float,
    inv_dx: float,
):
    """(v, B, ∇v) = Σ over the 27 stencil nodes of (w v_i, w v_i (x_i − x_p)ᵀ, v_i ∇wᵀ), unrolled, from the
    dense field of `shape` nodes that starts at vel[off] (slot 0 of a `GridView`; one field of the
    differentiable solver's K dense fields)."""
    vp = wp.vec3(0.0)
    B = wp.mat33(0.0)
    gradv = wp.mat33(0.0)
    for i in range(3):
        for j in range(3):
            for l in range(3):  # noqa: E741
                weight, grad, dpos = node_terms(i, j, l, f, w, dw, dx, inv_dx)
                vi = vel[off + flat(wp.vec3i(base[0] + i, base[1] + j, base[2] + l), wp.vec3i(0, 0, 0), shape)]
                vp = vp + weight * vi
                B = B + weight * wp.outer(vi, dpos)
                gradv = gradv + wp.outer(vi, grad)
    return vp, B, gradv
