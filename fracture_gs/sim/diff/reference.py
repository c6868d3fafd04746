"""Float64 pure-torch twin of a differentiable frame (`DiffSimulator.substeps`), for gradient checks by
central finite differences: the same equations on dense per-fragment fields, without boundaries
(checked scenes stay away from the walls and have no colliders)."""

from __future__ import annotations

import torch

from .. import reference as R
from .solver import FramePlan


def stress(F, material, mu, lam, released):
    """Kirchhoff τ of fixed-corotated (material 0) and neo-Hookean (1) from μ, λ, with band release."""
    F = F.double()
    mu, lam = mu.double(), lam.double()
    eye = torch.eye(3, dtype=torch.float64).expand(F.shape[0], 3, 3)
    U, s, V = R._svd(F)
    Rot = U @ V.transpose(1, 2)
    J = torch.det(F)
    fc = 2 * mu[:, None, None] * (F - Rot) @ F.transpose(1, 2) + (lam * (J - 1) * J)[:, None, None] * eye
    nh = mu[:, None, None] * (F @ F.transpose(1, 2) - eye) + (lam * torch.log(J.clamp_min(1e-6)))[:, None, None] * eye
    tau = torch.where((material == 0)[:, None, None], fc, nh)
    return tau * released.double()[:, None, None]


def frame(sim, plan: FramePlan, x, v, C, F, mu, lam, mass, volume):
    """The frame's substeps in float64 (x, v, C, F, parameters as torch tensors); returns (x, v, C, F)."""
    x, v, C, F = (t.double() for t in (x, v, C, F))
    field = plan.field.long().cpu()
    K = plan.fields
    eps_m, eps_b = sim.eps
    n = torch.tensor(sim._normal(plan), dtype=torch.float64)
    for _ in range(plan.n):
        tau = stress(F, sim.material.cpu(), mu, lam, plan.released.cpu())
        origin = tuple(o + i * sim.dx for o, i in zip(sim.origin, plan.lo))
        gm, gp, gb = R.p2g(
            x, v, C, mass, volume, tau, field, K, plan.shape, origin, sim.dx, plan.dt, band=plan.band.cpu()
        )
        gv = R.grid_update(gm, gp, gb, eps_m, eps_b, plan.dt, sim.cfg.gravity)
        if sim.spec.contact and K > 1:
            M = gm[0].numel()
            vv = gv.reshape(K, M, 3).transpose(0, 1)
            mm, bb = gm.reshape(K, M).T, gb.reshape(K, M).T
            frag = torch.arange(K).expand(M, K)
            vv = R.contact_fields(
                vv,
                mm,
                frag,
                bb,
                eps_m,
                eps_b,
                lambda a, b, lo, hi, M=M: n.expand(M, 3),
                e=float(sim.cfg.restitution),
                mu=float(sim.cfg.contact.friction),
            )
            gv = vv.transpose(0, 1).reshape(gv.shape)
        x, v, C, F = R.g2p(x, F, gv, field, origin, sim.dx, plan.dt)
    return x, v, C, F
