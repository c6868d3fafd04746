"""Differentiable MLS-MPM kernels: the same equations as `stencil.py`, `grid/kernels.py` and `physics/constitutive.py`,
written out-of-place (every launch reads one state and writes a new one, as `wp.Tape` needs) on
dense per-fragment fields [K · X·Y·Z], in a module compiled with backward kernels.

Adjoints come from Warp's automatic differentiation, except the fixed-corotated stress, whose SVD
derivative divides by s_i − s_j and is undefined at F = I (every particle at rest): its gradient is
written by hand from the polar rotation's derivative, which divides only by s_i + s_j
(`corotated_kirchhoff_grad`). Contact projection branches (approach or not, stick or slip) are
replayed as taken in the forward pass, which is their exact derivative almost everywhere.
"""

from __future__ import annotations

import warp as wp

from ..physics.boundary import Colliders, cuboid_velocity, plane_velocity, sphere_velocity, wall_velocity
from ..stencil import gather, node_terms, stencil

wp.set_module_options({"enable_backward": True})

SUM_EPS = 1e-6  # floor of s_i + s_j in the polar rotation's derivative (only reached by inverted, flat F)
MAX_BOUNDARIES = 4  # planes, cuboids and spheres each: the unrolled loops of `apply_boundaries_unrolled`


@wp.func
def polar_svd(F: wp.mat33):
    """F = U diag(s) Vᵀ with U, V rotations (det +1; the smallest s carries det F's sign), refined."""
    U, s, V = wp.svd3(F)
    U2, s2, V2 = wp.svd3(wp.transpose(U) * F * V)
    U = U * U2
    V = V * V2
    if wp.determinant(U) < 0.0:
        U = U * wp.diag(wp.vec3(1.0, 1.0, -1.0))
        s2 = wp.vec3(s2[0], s2[1], -s2[2])
    if wp.determinant(V) < 0.0:
        V = V * wp.diag(wp.vec3(1.0, 1.0, -1.0))
        s2 = wp.vec3(s2[0], s2[1], -s2[2])
    return U, s2, V


@wp.func
def cofactor(F: wp.mat33):
    """∂ det F / ∂F (= det F · F⁻ᵀ, defined for singular F too)."""
    return wp.mat33(
        F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1],
        F[1, 2] * F[2, 0] - F[1, 0] * F[2, 2],
        F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0],
        F[0, 2] * F[2, 1] - F[0, 1] * F[2, 2],
        F[0, 0] * F[2, 2] - F[0, 2] * F[2, 0],
        F[0, 1] * F[2, 0] - F[0, 0] * F[2, 1],
        F[0, 1] * F[1, 2] - F[0, 2] * F[1, 1],
        F[0, 2] * F[1, 0] - F[0, 0] * F[1, 2],
        F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0],
    )


@wp.func
def corotated_kirchhoff(F: wp.mat33, mu: float, lam: float):
    """Fixed-corotated τ = 2μ(F − R)Fᵀ + λ(J − 1)J I, R the polar rotation of F."""
    U, s, V = polar_svd(F)
    R = U * wp.transpose(V)
    J = wp.determinant(F)
    return 2.0 * mu * (F - R) * wp.transpose(F) + wp.identity(n=3, dtype=float) * (lam * (J - 1.0) * J)


@wp.func_grad(corotated_kirchhoff)
def corotated_kirchhoff_grad(F: wp.mat33, mu: float, lam: float, adj_ret: wp.mat33):
    """Hand-written adjoint. With G = ∂L/∂τ:  ∂L/∂F = 2μ G F + 2μ Gᵀ(F − R) + λ(2J − 1) tr G · cof F
    + (∂R/∂F)ᵀ[−2μ G F]; for F = R S, dR = R Ω with Ω solving ΩS + SΩ = Rᵀ dF − dFᵀ R, which in S's
    eigenbasis V is Ω'_ij = W'_ij / (s_i + s_j): the adjoint of A = ∂L/∂R is 2 R V C Vᵀ with
    C_ij = (Vᵀ skew(Rᵀ A) V)_ij / (s_i + s_j)."""
    G = adj_ret
    U, s, V = polar_svd(F)
    R = U * wp.transpose(V)
    J = wp.determinant(F)
    I = wp.identity(n=3, dtype=float)
    GF = G * F
    dF = 2.0 * mu * GF + 2.0 * mu * wp.transpose(G) * (F - R) + (lam * (2.0 * J - 1.0) * wp.trace(G)) * cofactor(F)
    A = -2.0 * mu * GF
    B = wp.transpose(R) * A
    Bs = 0.5 * (B - wp.transpose(B))
    Cp = wp.transpose(V) * Bs * V
    C = wp.mat33(0.0)
    for i in range(3):
        for j in range(3):
            if i != j:
                C[i, j] = Cp[i, j] / wp.max(s[i] + s[j], SUM_EPS)
    dF = dF + 2.0 * R * (V * C * wp.transpose(V))
    wp.adjoint[F] += dF
    wp.adjoint[mu] += wp.ddot(G, 2.0 * (F - R) * wp.transpose(F))
    wp.adjoint[lam] += wp.ddot(G, I) * (J - 1.0) * J


@wp.kernel
def stress(
    F: wp.array(dtype=wp.mat33),  # [N]
    material: wp.array(dtype=wp.int32),  # [N] 0 fixed-corotated, 1 neo-Hookean
    mu: wp.array(dtype=float),  # [N]
    lam: wp.array(dtype=float),  # [N]
    released: wp.array(dtype=float),  # [N] 1 − γ_p where the band's stress is released, else 1
    tau: wp.array(dtype=wp.mat33),  # [N] out: Kirchhoff stress
):
    p = wp.tid()
    Fp = F[p]
    t = wp.mat33(0.0)
    if material[p] == 0:
        t = corotated_kirchhoff(Fp, mu[p], lam[p])
    else:
        I = wp.identity(n=3, dtype=float)
        t = mu[p] * (Fp * wp.transpose(Fp) - I) + I * (lam[p] * wp.log(wp.max(wp.determinant(Fp), 1e-6)))
    tau[p] = t * released[p]


@wp.kernel
def p2g(
    x: wp.array(dtype=wp.vec3),
    v: wp.array(dtype=wp.vec3),
    C: wp.array(dtype=wp.mat33),
    tau: wp.array(dtype=wp.mat33),
    mass: wp.array(dtype=float),
    volume: wp.array(dtype=float),
    field: wp.array(dtype=wp.int32),  # [N] routed field k
    band: wp.array(dtype=float),  # [N] γ_p (band mass for the contact gate)
    dt: float,
    origin: wp.vec3,
    dx: float,
    inv_dx: float,
    shape: wp.vec3i,
    grid_m: wp.array(dtype=float),  # [K · X·Y·Z] out (accumulated)
    grid_p: wp.array(dtype=wp.vec3),  # [K · X·Y·Z] out
    grid_b: wp.array(dtype=float),  # [K · X·Y·Z] out: band mass
):
    """m^k += w m_p; p^k += w m_p (v_p + C_p (x_i − x_p)) − Δt V⁰ τ_p ∇w; m_band^k += γ_p w m_p."""
    p = wp.tid()
    base, f, w, dw = stencil(x[p], origin, inv_dx, shape)
    m = mass[p]
    force = -dt * volume[p] * tau[p]
    off = field[p] * shape[0] * shape[1] * shape[2]
    for i in range(3):
        for j in range(3):
            for l in range(3):  # noqa: E741
                weight, grad, dpos = node_terms(i, j, l, f, w, dw, dx, inv_dx)
                n = off + ((base[0] + i) * shape[1] + base[1] + j) * shape[2] + base[2] + l
                wp.atomic_add(grid_m, n, weight * m)
                wp.atomic_add(grid_p, n, weight * m * (v[p] + C[p] * dpos) + force * grad)
                wp.atomic_add(grid_b, n, band[p] * weight * m)


@wp.kernel
def normalize(
    grid_m: wp.array(dtype=float),
    grid_p: wp.array(dtype=wp.vec3),
    eps_m: float,
    dt: float,
    gravity: wp.vec3,
    grid_v: wp.array(dtype=wp.vec3),
):
    """v = p/m + Δt g where m > ε_m, else 0."""
    n = wp.tid()
    v = wp.vec3(0.0)
    if grid_m[n] > eps_m:
        v = grid_p[n] / grid_m[n] + dt * gravity
    grid_v[n] = v


@wp.kernel
def contact_pair(
    grid_m: wp.array(dtype=float),
    grid_b: wp.array(dtype=float),
    v_in: wp.array(dtype=wp.vec3),  # [K · X·Y·Z]
    a: int,  # the pair of fields, a < b by fragment id
    b: int,
    n_nodes: int,
    K: int,
    normal: wp.vec3,  # from a into b
    eps_m: float,
    eps_b: float,
    e: float,
    mu: float,
    v_out: wp.array(dtype=wp.vec3),  # [K · X·Y·Z]: v_in with fields a, b projected
):
    """The approach-only, momentum-conserving contact of `physics/contact.py` between fields a and b."""
    n = wp.tid()
    for k in range(K):
        v_out[k * n_nodes + n] = v_in[k * n_nodes + n]
    ia = a * n_nodes + n
    ib = b * n_nodes + n
    ma = grid_m[ia]
    mb = grid_m[ib]
    if ma > eps_m and mb > eps_m and grid_b[ia] > eps_b and grid_b[ib] > eps_b:
        va = v_in[ia]
        vb = v_in[ib]
        un = wp.dot(vb - va, normal)
        if un < 0.0:
            inv = 1.0 / ma + 1.0 / mb
            J = -(1.0 + e) * un / inv
            wa = va - (J / ma) * normal
            wb = vb + (J / mb) * normal
            if mu > 0.0:
                u = wb - wa
                ut = u - wp.dot(u, normal) * normal
                sl = wp.length(ut)
                if sl > 0.0:
                    Jt = wp.min(sl / inv, mu * J)
                    t = ut / sl
                    wa = wa + (Jt / ma) * t
                    wb = wb - (Jt / mb) * t
            v_out[ia] = wa
            v_out[ib] = wb


@wp.func
def apply_boundaries_unrolled(v: wp.vec3, node: wp.vec3i, xi: wp.vec3, t: float, c: Colliders):
    """`boundary.apply_boundaries` (cuboids, spheres, planes, walls, in that order) with loops of a fixed
    length MAX_BOUNDARIES, which Warp unrolls: its adjoint of a loop over an array's length keeps none of
    the projections (the gradient passes through a plane or sphere as if it were not there), the
    unrolled one differentiates each operator."""
    out = v
    for b in range(MAX_BOUNDARIES):
        if b < c.box_lower.shape[0]:
            out = cuboid_velocity(
                out, xi, t, c.box_lower[b], c.box_upper[b], c.box_velocity[b], c.box_time[b], c.box_push[b]
            )
    for b in range(MAX_BOUNDARIES):
        if b < c.sphere_radius.shape[0]:
            vs = c.sphere_velocity[b]
            out = sphere_velocity(out, xi, t, c.sphere_centre[b], c.sphere_radius[b], vs, c.sphere_time[b])
    for b in range(MAX_BOUNDARIES):
        if b < c.plane_point.shape[0]:
            out = plane_velocity(out, xi, c.plane_point[b], c.plane_normal[b], c.plane_mode[b], c.plane_mu[b])
    return wall_velocity(out, node, c.shape, c.wall_cells)


@wp.kernel
def boundaries(
    grid_m: wp.array(dtype=float),
    v_in: wp.array(dtype=wp.vec3),
    eps_m: float,
    origin: wp.vec3,
    dx: float,
    shape: wp.vec3i,
    lo: wp.vec3i,
    t: float,
    colliders: Colliders,
    v_out: wp.array(dtype=wp.vec3),
):
    """Every grid-side boundary operator on every active field (after contact). The fields cover a box
    of the grid: `origin` is its node 0, `lo` that node's index in the whole grid (for the walls)."""
    i = wp.tid()
    n_nodes = shape[0] * shape[1] * shape[2]
    n = i % n_nodes
    node = wp.vec3i(n // (shape[1] * shape[2]), (n // shape[2]) % shape[1], n % shape[2])
    v = v_in[i]
    if grid_m[i] > eps_m:
        xi = origin + wp.vec3(float(node[0]), float(node[1]), float(node[2])) * dx
        v = apply_boundaries_unrolled(v, node + lo, xi, t, colliders)
    v_out[i] = v


@wp.kernel
def g2p(
    x: wp.array(dtype=wp.vec3),
    F: wp.array(dtype=wp.mat33),
    field: wp.array(dtype=wp.int32),
    grid_v: wp.array(dtype=wp.vec3),
    dt: float,
    origin: wp.vec3,
    dx: float,
    inv_dx: float,
    shape: wp.vec3i,
    lower: wp.vec3,
    upper: wp.vec3,
    x_out: wp.array(dtype=wp.vec3),
    v_out: wp.array(dtype=wp.vec3),
    C_out: wp.array(dtype=wp.mat33),
    F_out: wp.array(dtype=wp.mat33),
):
    """v = Σ w v_i; C = 4/Δx² Σ w v_i (x_i − x_p)ᵀ; F ← (I + Δt Σ v_i ∇wᵀ) F; x ← x + Δt v (own field)."""
    p = wp.tid()
    base, f, w, dw = stencil(x[p], origin, inv_dx, shape)
    vp, B, gradv = gather(grid_v, field[p] * shape[0] * shape[1] * shape[2], shape, base, f, w, dw, dx, inv_dx)
    v_out[p] = vp
    C_out[p] = B * (4.0 * inv_dx * inv_dx)
    F_out[p] = (wp.identity(n=3, dtype=float) + dt * gradv) * F[p]
    xn = x[p] + dt * vp
    x_out[p] = wp.vec3(
        wp.clamp(xn[0], lower[0], upper[0]), wp.clamp(xn[1], lower[1], upper[1]), wp.clamp(xn[2], lower[2], upper[2])
    )
