"""`FractureSim(..., differentiable=True)`: the scene path of the torch module, with gradients.

Gaussians and physical parameters in (torch tensors that may require grad), per-frame means and
covariances out, differentiable through `fracture_gs.sim.diff.DiffSimulator` frames. Held constant
(no gradient): the particle volumes (from the Gaussians' cell occupancy at rest), each frame's Δt and
substep count, the fracture topology (found once by a plain run, or given), and the rotation R(F)
used to turn the SH coefficients (covariances and means carry the gradient).
"""

from __future__ import annotations

import copy

import torch

from .io import GaussianSet
from .pipeline import make_simulator, simulate
from .render.gaussians import polar_rotation
from .sim import Particles
from .sim.diff import DiffSimulator
from .sim.physics.constitutive import lame
from .variants import variant_spec


def _per_particle(value, default: torch.Tensor) -> torch.Tensor:  # scalar/[N] -> [N]
    if value is None:
        return default
    t = torch.as_tensor(value, device=default.device, dtype=default.dtype) if not torch.is_tensor(value) else value
    return t.to(default.device).expand(default.shape) if t.dim() == 0 else t.to(default.device)


def find_topology(module, gs: GaussianSet, device: str) -> list:
    """The fracture history of a plain run of the module's config (cached on the module): the fixed
    topology the differentiable frames replay."""
    if module.topology is not None:
        return module.topology if isinstance(module.topology, list) else [module.topology]
    if not variant_spec(module.variant).needs_provider:
        return []
    with torch.no_grad():
        plain = gs.replace(**{k: getattr(gs, k).detach() for k in ("means", "quats", "scales", "opacities", "sh")})
        sim = make_simulator(module.cfg, plain, module.variant, device)
        for _ in simulate(
            sim,
            plain.covariances().to(device, torch.float32),
            module.cfg.frames,
            module.cfg.frame_dt,
            diagnostics=False,
        ):
            pass
    module.topology = list(sim.topologies)
    return module.topology


def differentiable_forward(module, gs: GaussianSet, E=None, nu=None, density=None, velocity=None) -> dict:
    """Run the module's frames differentiably; see `FractureSim.forward` for the returned dict."""
    cfg = module.cfg
    device = module._device(gs)
    topologies = find_topology(module, gs, device)
    detached = gs.replace(means=gs.means.detach())
    P = Particles.from_gaussians(detached, cfg).to(device)
    E_t = _per_particle(E, P.E)
    nu_t = _per_particle(nu, P.nu)
    rho_t = _per_particle(density, P.mass / P.volume)
    mu, lam = lame(E_t, nu_t)
    mass = rho_t * P.volume
    x = gs.means.to(device, torch.float32)
    v = P.v if velocity is None else torch.as_tensor(velocity, dtype=torch.float32, device=device).expand_as(x)
    n = x.shape[0]
    C = torch.zeros(n, 3, 3, device=device)
    F = torch.eye(3, device=device).expand(n, 3, 3).contiguous()
    sim_cfg = copy.deepcopy(cfg.sim)
    sim_cfg.variant = module.variant
    with torch.no_grad():
        mu0, lam0 = lame(E_t.detach().double(), nu_t.detach().double())
        wave = float(torch.sqrt((lam0 + 2 * mu0) / rho_t.detach().double()).max())
    sim = DiffSimulator(sim_cfg, x.detach(), device, material=P.material, topologies=topologies, wave_speed=wave)
    module.last_simulator = sim
    cov0 = gs.covariances().to(device, torch.float32)
    means, covars, rotations, fragments = [x], [cov0], [torch.eye(3, device=device).expand(n, 3, 3)], []
    for f in range(cfg.frames):
        topo = sim.topology_at(f)
        fragments.append(topo.fragment.to(device) if topo is not None else torch.full((n,), -1, device=device))
        x, v, C, F = sim.step(cfg.frame_dt, x, v, C, F, mu, lam, mass, P.volume)
        means.append(x)
        covars.append(F @ cov0 @ F.transpose(1, 2))
        rotations.append(polar_rotation(F.detach()))
    topo = sim.topology_at(cfg.frames)
    fragments.append(topo.fragment.to(device) if topo is not None else torch.full((n,), -1, device=device))
    return {
        "means": torch.stack(means),
        "covars": torch.stack(covars),
        "rotations": torch.stack(rotations),
        "fragment": torch.stack(fragments).to(torch.int32),
        "time": torch.tensor([i * cfg.frame_dt for i in range(cfg.frames + 1)]),
        "metrics": [],
    }
