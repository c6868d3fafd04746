"""Float64 pure-torch twins of every kernel (the specification the Warp kernels are tested against).

Readable rather than fast: each function is the paper's equation in vectorized torch.
"""

from __future__ import annotations

import torch

# Written here from the formulas, not imported from the kernels' module: a wrong constant or Lamé parameter in
# the code under test must show up as a kernel-vs-reference difference.
SIGMA_MIN = 1e-4  # smallest principal stretch whose log is taken (Hencky strain of an inverted element stays finite)


def lame(E, nu):
    """Lamé parameters μ = E / (2(1 + ν)), λ = E ν / ((1 + ν)(1 − 2ν)) (floats or tensors)."""
    mu = E / (2.0 * (1.0 + nu))
    lam = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    return mu, lam


def _svd(F):
    """F = U diag(σ) Vᵀ with det U = det V = +1 (the smallest σ carries det F's sign)."""
    U, s, Vh = torch.linalg.svd(F)
    V = Vh.transpose(-1, -2)
    fix_u = torch.det(U) < 0
    fix_v = torch.det(V) < 0
    U[fix_u, :, 2] *= -1
    s[fix_u, 2] *= -1
    V[fix_v, :, 2] *= -1
    s[fix_v, 2] *= -1
    return U, s, V


def stress(F, material, E, nu, yield_stress, alpha, band=None, release=False):
    """Returns (τ [N,3,3], F after plastic return [N,3,3], Δγ_vm [N])."""
    F = F.double()
    mu, lam = lame(E.double(), nu.double())
    n = F.shape[0]
    eye = torch.eye(3, dtype=torch.float64).expand(n, 3, 3)
    U, s, V = _svd(F)
    J = torch.det(F)
    tau = torch.zeros(n, 3, 3, dtype=torch.float64)
    F_new = F.clone()
    dgamma = torch.zeros(n, dtype=torch.float64)
    # fixed-corotated
    R = U @ V.transpose(1, 2)
    fc = 2 * mu[:, None, None] * (F - R) @ F.transpose(1, 2) + (lam * (J - 1) * J)[:, None, None] * eye
    # neo-Hookean
    nh = mu[:, None, None] * (F @ F.transpose(1, 2) - eye) + (lam * torch.log(J.clamp_min(1e-6)))[:, None, None] * eye
    # Hencky-based plasticity
    eps = torch.log(s.clamp_min(SIGMA_MIN))
    tr = eps.sum(1, keepdim=True)
    dev = eps - tr / 3
    norm = dev.norm(dim=1, keepdim=True)
    # von Mises radial return
    dg_vm = (norm - yield_stress.double()[:, None] / (2 * mu[:, None])).clamp_min(0)
    eps_vm = torch.where((dg_vm > 0) & (norm > 0), eps - dev * dg_vm / norm.clamp_min(1e-300), eps)
    # Drucker–Prager
    dg_dp = norm + (3 * lam[:, None] + 2 * mu[:, None]) / (2 * mu[:, None]) * tr * alpha.double()[:, None]
    eps_dp = torch.where((dg_dp > 0) & (norm > 0), eps - dev * dg_dp / norm.clamp_min(1e-300), eps)
    eps_dp = torch.where(tr >= 0, torch.zeros_like(eps), eps_dp)
    for model, e in ((2, eps_vm), (3, eps_dp)):
        m = material == model
        if m.any():
            d = 2 * mu[m, None] * e[m] + lam[m, None] * e[m].sum(1, keepdim=True)
            tau[m] = U[m] @ torch.diag_embed(d) @ U[m].transpose(1, 2)
            F_new[m] = U[m] @ torch.diag_embed(torch.exp(e[m])) @ V[m].transpose(1, 2)
    tau[material == 0] = fc[material == 0]
    tau[material == 1] = nh[material == 1]
    dgamma[material == 2] = dg_vm[material == 2, 0]
    if release and band is not None:
        tau[band.bool()] = 0
    return tau, F_new, dgamma


def stencil(x, origin, dx):
    """Node indices [N,27,3], weights [N,27], gradients [N,27,3], offsets x_i − x_p [N,27,3]."""
    xi = (x.double() - torch.as_tensor(origin, dtype=torch.float64)) / dx
    base = torch.floor(xi - 0.5)
    f = xi - base
    w = torch.stack([0.5 * (1.5 - f) ** 2, 0.75 - (f - 1) ** 2, 0.5 * (f - 0.5) ** 2], dim=1)  # [N,3(a),3(axis)]
    dw = torch.stack([f - 1.5, -2 * (f - 1), f - 0.5], dim=1)
    off = torch.stack(torch.meshgrid(*[torch.arange(3)] * 3, indexing="ij"), -1).reshape(27, 3)
    wa = torch.stack([w[:, off[:, a], a] for a in range(3)], -1)  # [N,27,3]
    dwa = torch.stack([dw[:, off[:, a], a] for a in range(3)], -1)
    weight = wa.prod(-1)
    grad = (
        torch.stack(
            [
                dwa[..., 0] * wa[..., 1] * wa[..., 2],
                wa[..., 0] * dwa[..., 1] * wa[..., 2],
                wa[..., 0] * wa[..., 1] * dwa[..., 2],
            ],
            -1,
        )
        / dx
    )
    dpos = (off[None].double() - f[:, None, :]) * dx
    nodes = base.long()[:, None, :] + off[None]
    return nodes, weight, grad, dpos


def p2g(x, v, C, mass, volume, tau, field, n_fields, shape, origin, dx, dt, band=None):
    """Eqs. single_mass / multifield_p2g into `n_fields` dense fields; `field` [N] routes particles."""
    nodes, weight, grad, dpos = stencil(x, origin, dx)
    m = mass.double()[:, None] * weight  # [N,27]
    mom = m[..., None] * (v.double()[:, None, :] + torch.einsum("nij,nkj->nki", C.double(), dpos))
    mom = mom - dt * volume.double()[:, None, None] * torch.einsum("nij,nkj->nki", tau.double(), grad)
    X, Y, Z = shape
    flat = ((field.long()[:, None] * X + nodes[..., 0]) * Y + nodes[..., 1]) * Z + nodes[..., 2]
    size = n_fields * X * Y * Z
    gm = torch.zeros(size, dtype=torch.float64).index_add_(0, flat.reshape(-1), m.reshape(-1))
    gp = torch.zeros(size, 3, dtype=torch.float64).index_add_(0, flat.reshape(-1), mom.reshape(-1, 3))
    gb = torch.zeros(size, dtype=torch.float64)
    if band is not None:
        gb.index_add_(0, flat.reshape(-1), (m * band.double()[:, None]).reshape(-1))
    return gm.reshape(n_fields, *shape), gp.reshape(n_fields, *shape, 3), gb.reshape(n_fields, *shape)


def contact(v0, v1, m0, m1, n, e=0.0):
    """Eqs. impulse / contact_update at every node where u_n < 0 ([M,3] velocities, [M] masses)."""
    un = (v1 - v0) @ n
    J = torch.where(un < 0, -(1 + e) * un / (1 / m0 + 1 / m1), torch.zeros_like(un))
    return v0 - (J / m0)[:, None] * n, v1 + (J / m1)[:, None] * n


def grid_update(gm, gp, gb, eps_m, eps_b, dt, gravity, normal=None, e=0.0, project=False):
    """Normalize + gravity per active field, then the gated contact projection (no boundaries)."""
    g = torch.as_tensor(gravity, dtype=torch.float64)
    active = gm > eps_m
    v = torch.where(active[..., None], gp / gm.clamp_min(1e-300)[..., None] + dt * g, torch.zeros_like(gp))
    if project and gm.shape[0] == 2:
        n = torch.as_tensor(normal, dtype=torch.float64)
        gate = active[0] & active[1] & (gb[0] > eps_b) & (gb[1] > eps_b)
        v0, v1 = contact(v[0][gate], v[1][gate], gm[0][gate], gm[1][gate], n, e)
        v[0][gate] = v0
        v[1][gate] = v1
    return v


def g2p(x, F, gv, field, origin, dx, dt):
    """Eqs. field_g2p / field_apic / field_deformation: returns (x, v, C, F)."""
    nodes, weight, grad, dpos = stencil(x, origin, dx)
    vi = gv[field.long()[:, None], nodes[..., 0], nodes[..., 1], nodes[..., 2]]  # [N,27,3]
    v = (weight[..., None] * vi).sum(1)
    C = 4 / dx**2 * torch.einsum("nk,nki,nkj->nij", weight, vi, dpos)
    gradv = torch.einsum("nki,nkj->nij", vi, grad)
    F_new = (torch.eye(3, dtype=torch.float64) + dt * gradv) @ F.double()
    return x.double() + dt * v, v, C, F_new


def contact_fields(v, m, frag, band, eps_m, eps_b, normals, e=0.0, mu=0.0, touching=None):
    """Pairwise contact at M nodes with S fields each (v [M,S,3], m [M,S], frag [M,S] (−1: empty),
    band [M,S], normals(a_slot, b_slot, lo_slot, hi_slot) → [M,3] unit normals from lo into hi,
    touching(a_slot, b_slot) → [M] bool contact gate, default: both band-supported):
    slot pairs a < b in order, each oriented by fragment id, approach-only normal impulse with
    restitution e, then Coulomb friction capped at μ·J (physics/contact.py, float64)."""
    v = v.double().clone()
    M, S = m.shape
    for a in range(S):
        for b in range(a + 1, S):
            gate = (band[:, a] > eps_b) & (band[:, b] > eps_b) if touching is None else touching(a, b)
            ok = (frag[:, a] >= 0) & (frag[:, b] >= 0) & (m[:, a] > eps_m) & (m[:, b] > eps_m) & gate
            swap = frag[:, b] < frag[:, a]
            lo = torch.where(swap, b, a)
            hi = torch.where(swap, a, b)
            rows = torch.arange(M)
            n = normals(a, b, lo, hi).double()
            v_lo, v_hi = v[rows, lo], v[rows, hi]
            m_lo, m_hi = m[rows, lo].double(), m[rows, hi].double()
            un = ((v_hi - v_lo) * n).sum(1)
            go = ok & (un < 0)
            inv = 1 / m_lo.clamp_min(1e-300) + 1 / m_hi.clamp_min(1e-300)
            J = torch.where(go, -(1 + e) * un / inv, torch.zeros_like(un))
            w_lo = v_lo - (J / m_lo.clamp_min(1e-300))[:, None] * n
            w_hi = v_hi + (J / m_hi.clamp_min(1e-300))[:, None] * n
            if mu > 0:
                u = w_hi - w_lo
                ut = u - (u * n).sum(1, keepdim=True) * n
                s = ut.norm(dim=1)
                Jt = torch.where(go & (s > 0), torch.minimum(s / inv, mu * J), torch.zeros_like(s))
                t = ut / s.clamp_min(1e-300)[:, None]
                w_lo = w_lo + (Jt / m_lo.clamp_min(1e-300))[:, None] * t
                w_hi = w_hi - (Jt / m_hi.clamp_min(1e-300))[:, None] * t
            v[rows[go], lo[go]] = w_lo[go]
            v[rows[go], hi[go]] = w_hi[go]
    return v
