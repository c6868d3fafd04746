"""`sim/diff/reference.py`, the float64 twin of a differentiable frame: where the frame's box of nodes sits
must not change the physics. A frame run on a box starting at node lo = (4, 3, 5) moves the particles
exactly as the same frame on a box from node 0 that covers them (the twin has no boundaries), and the
stress it uses is the fixed-corotated / neo-Hookean Kirchhoff stress (zero at rest, zero where released)."""

import types

import torch

from fracture_gs.sim.diff import reference as DR
from fracture_gs.sim.diff.solver import FramePlan


def _scene(g, n=64):
    dx = 1.0 / 16
    x = (torch.tensor([7.0, 6.0, 8.0]) + 2.0 * torch.rand(n, 3, generator=g)) * dx  # nodes 7-9, 6-8, 8-10
    v = 0.3 * torch.randn(n, 3, generator=g)
    C = 0.5 * torch.randn(n, 3, 3, generator=g)
    F = torch.eye(3) + 0.05 * torch.randn(n, 3, 3, generator=g)
    sim = types.SimpleNamespace(
        eps=(1e-12, 1e-12),
        _normal=lambda plan: (1.0, 0.0, 0.0),
        material=torch.zeros(n, dtype=torch.int32),
        dx=dx,
        origin=(0.0, 0.0, 0.0),
        cfg=types.SimpleNamespace(
            gravity=(0.0, 0.0, -9.8), restitution=0.0, contact=types.SimpleNamespace(friction=0.0)
        ),
        spec=types.SimpleNamespace(contact=False),
    )
    mu, lam = torch.full((n,), 3e3, dtype=torch.float64), torch.full((n,), 2e3, dtype=torch.float64)
    mass, volume = torch.full((n,), 1e-3), torch.full((n,), 1e-6)
    return sim, (x, v, C, F, mu, lam, mass, volume)


def _plan(n, lo, shape):
    return FramePlan(
        n=2,
        dt=1e-3,
        t0=0.0,
        field=torch.zeros(n, dtype=torch.int32),
        released=torch.ones(n),
        band=torch.zeros(n),
        fields=1,
        lo=lo,
        shape=shape,
    )


def test_a_frame_on_an_offset_box_moves_particles_as_on_a_box_from_the_origin(seed):
    """Box [lo, lo + shape) with lo = (4, 3, 5) against [0, 16)³ covering the same particles: x, v, C and F
    after two substeps agree to float64 rounding."""
    g = torch.Generator().manual_seed(seed)
    sim, state = _scene(g)
    n = state[0].shape[0]
    full = DR.frame(sim, _plan(n, (0, 0, 0), (16, 16, 16)), *state)
    offset = DR.frame(sim, _plan(n, (4, 3, 5), (10, 10, 10)), *state)
    for a, b in zip(full, offset):
        assert torch.allclose(a, b, rtol=0, atol=1e-9)
    assert float((full[0] - state[0].double()).abs().max()) > 1e-5  # the particles did move


def test_twin_stress_vanishes_at_rest_and_where_released():
    """τ(F = R) = 0 for a rotation with both models, and a released particle (factor 0) carries no stress
    whatever its deformation; a stretched one does."""
    c, s = 0.6, 0.8
    R = torch.tensor([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], dtype=torch.float64)
    F = torch.stack([R, R, torch.diag(torch.tensor([1.2, 1.0, 1.0], dtype=torch.float64))] * 2)
    material = torch.tensor([0, 0, 0, 1, 1, 1])
    mu, lam = torch.full((6,), 3.0, dtype=torch.float64), torch.full((6,), 2.0, dtype=torch.float64)
    released = torch.tensor([1.0, 0.0, 1.0, 1.0, 0.0, 1.0])
    tau = DR.stress(F, material, mu, lam, released)
    assert float(tau[[0, 1, 3, 4]].abs().max()) < 1e-12
    # uniaxial stretch 1.2: fixed-corotated τ_xx = 2μ(1.2 − 1)1.2 + λ(J − 1)J = 1.44 + 0.48; neo-Hookean
    # τ_xx = μ(1.44 − 1) + λ ln 1.2
    assert abs(float(tau[2, 0, 0]) - (2 * 3.0 * 0.2 * 1.2 + 2.0 * 0.2 * 1.2)) < 1e-12
    assert abs(float(tau[5, 0, 0]) - (3.0 * 0.44 + 2.0 * torch.log(torch.tensor(1.2, dtype=torch.float64)))) < 1e-12
