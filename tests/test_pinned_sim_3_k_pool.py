"""The slot storage's pool pass with mass-gradient normals (`normal_kernels.pool_mass_gradients`, then
`transfer_kernels.grid_update_pool`), on fields written straight into the slots (`simutil.fill_slots`):

- the pass takes each pair's normal from the two fields' mass gradients, n = (∇m¹ − ∇m⁰)/|…|, not from the
  fragment centroids or one field's gradient alone: fields whose masses grow along −y and +z meet along
  (0, 1, 1)/√2 though the centroids lie along x;
- ∇m^k of a slot is the central difference of fragment k's nodal masses for a field holding more than ε_m, and
  exactly zero for one holding ε_m or less (the same threshold the pass uses for an active field), in slot 0 and
  in a pool slot alike.

An 8³ grid, two fragments, on the CPU."""

import torch
import warp as wp
from simutil import block, fill_slots, particles

from fracture_gs import sim as S
from fracture_gs.sim.grid.layout import OWNER_MASK
from fracture_gs.sim.grid.normal_kernels import pool_mass_gradients
from fracture_gs.sim.physics.contact import NORMAL_MASS_GRADIENT

SHAPE = (8, 8, 8)


def _sim():
    """Two blocks side by side along x, cut between them (fragment centroids along +x), mass-gradient normals,
    slot storage with a pool row at every node."""
    a, vol = block((0.3, 0.4, 0.4), (0.45, 0.6, 0.6), 0.025)
    b, _ = block((0.55, 0.4, 0.4), (0.7, 0.6, 0.6), 0.025)
    cfg = S.SimConfig(
        dx=1 / 8,
        grid_shape=SHAPE,
        gravity=(0, 0, 0),
        variant="full",
        wall_cells=0,
        field_slots=4,
        contact=S.ContactConfig(friction=0.0, normal="mass_gradient"),
        grid_storage="slots",
    )
    sim = S.Simulator(cfg, particles(torch.cat([a, b]), vol), device="cpu")
    sim.latch(S.Topology.from_plane(sim.particles.x, (0.5, 0.5, 0.5), (1.0, 0.0, 0.0), 0.0))
    assert sim.normal_mode == NORMAL_MASS_GRADIENT
    c = sim.centroids[:2].double()
    assert float(c[1, 0] - c[0, 0]) > 0.1 and float((c[1] - c[0])[1:].abs().max()) < 1e-6, "centroids along +x"
    sim.grid.ensure_pool(2 * sim.grid.n_nodes)
    return sim


def _central(m):
    """∇m [K, X, Y, Z, 3] by central differences per axis over 2Δx, neighbours clamped into the grid."""
    pad = torch.nn.functional.pad(m[None], (1, 1, 1, 1, 1, 1), mode="replicate")[0]
    return torch.stack(
        [
            pad[:, 2:, 1:-1, 1:-1] - pad[:, :-2, 1:-1, 1:-1],
            pad[:, 1:-1, 2:, 1:-1] - pad[:, 1:-1, :-2, 1:-1],
            pad[:, 1:-1, 1:-1, 2:] - pad[:, 1:-1, 1:-1, :-2],
        ],
        -1,
    ) * (0.5 * SHAPE[0])


def test_pool_contact_normals_come_from_the_fields_mass_gradients():
    """Field 0's mass falls along +y and field 1's rises along +z (m⁰ + m¹ ≥ 2 ρ̄Δx³ fills every node), so the pair
    meets along n = (∇m¹ − ∇m⁰)/|…|, (0, 1, 1)/√2 inside the grid and tilted at its faces (one-sided differences):
    it depends on both fields' gradients. With v⁰ = (0.3, 1, 0.5) and v¹ = (−0.2, −1, −0.5) approaching along
    every such n, frictionless and e = 0, each field gets the momentum-conserving inelastic impulse J n,
    J = −u_n / (1/m⁰ + 1/m¹), u_n = (v¹ − v⁰)·n: v⁰ − (J/m⁰) n and v¹ + (J/m¹) n. The fragment centroids lie
    along x: normals taken from them, or from one field's gradient alone, push elsewhere."""
    sim = _sim()
    idx = torch.meshgrid(*[torch.arange(s, dtype=torch.float64) for s in SHAPE], indexing="ij")
    nm = sim.node_mass
    m = torch.stack([nm * (1.0 + 0.1 * (7 - idx[1])), nm * (1.0 + 0.1 * idx[2])])  # [2, X, Y, Z]
    v = torch.tensor([[0.3, 1.0, 0.5], [-0.2, -1.0, -0.5]], dtype=torch.float64)[:, None, None, None, :]
    v = v.expand(2, *SHAPE, 3)
    fill_slots(sim.grid, m, v)
    sim.update_grid(1e-3)
    got = sim.grid.velocity.double().cpu()  # [2, X, Y, Z, 3]
    mf = m.float().double()
    grad = _central(mf)
    n = torch.nn.functional.normalize(grad[1] - grad[0], dim=-1)  # [X, Y, Z, 3]
    torch.testing.assert_close(n[3, 3, 3], torch.tensor([0.0, 1.0, 1.0], dtype=torch.float64) / 2**0.5)
    un = ((v[1] - v[0]) * n).sum(-1)
    assert bool((un < 0).all()), "the fields approach at every node"
    J = -un / (1.0 / mf[0] + 1.0 / mf[1])
    want = torch.stack([v[0] - (J / mf[0])[..., None] * n, v[1] + (J / mf[1])[..., None] * n])
    torch.testing.assert_close(got, want, rtol=0, atol=2e-6)
    p0, p1 = (mf[..., None] * v).sum(0), (mf[..., None] * got).sum(0)
    assert float((p1 - p0).abs().max()) <= 1e-5 * float(p0.abs().max()), "node momentum"


def _row(g, node):
    return int(torch.nonzero(g.key.cpu() == node).flatten()[0])


def test_pool_mass_gradient_is_zero_for_a_field_at_the_activity_threshold():
    """At interior nodes: ∇m^k of a field with m = ε_m exactly (float32, as the kernel compares) is exactly zero,
    and of one with the next float32 above ε_m the central difference (m^k(i + e_a) − m^k(i − e_a)) / 2Δx per
    axis; in slot 0 (the [capacity] buffer) and in pool slot 1 (its velocity entry). Elsewhere every slot holds
    its field's central difference."""
    sim = _sim()
    g = sim.grid
    gen = torch.Generator().manual_seed(11)
    m = sim.node_mass * (0.2 + torch.rand(2, *SHAPE, generator=gen, dtype=torch.float64))
    eps = torch.tensor(sim.eps_m, dtype=torch.float32)
    above = torch.nextafter(eps, torch.tensor(1.0))
    at = {(0, (2, 3, 4)): eps, (0, (5, 4, 3)): above, (1, (3, 5, 2)): eps, (1, (4, 2, 5)): above}
    for (k, node), value in at.items():
        m[(k, *node)] = float(value)
    fill_slots(g, m, torch.zeros(2, *SHAPE, 3, dtype=torch.float64))
    grad0 = sim.slots.pool_gradient_buffer()
    wp.launch(pool_mass_gradients, dim=g.capacity * g.slots, inputs=[g.view, sim.eps_m, grad0], device="cpu")
    mf = m.float().double()
    want = _central(mf)  # [2, X, Y, Z, 3]
    for (k, node), value in at.items():
        assert float(mf[(k, *node)]) == float(value)
        want[(k, *node)] = 0.0 if value == eps else want[(k, *node)]
    S1 = g.slots - 1
    got = torch.zeros(2, *SHAPE, 3, dtype=torch.float64)
    for n in range(g.n_nodes):
        r = _row(g, n)
        node = (n // 64, (n // 8) % 8, n % 8)
        assert int(g._owner[n] & OWNER_MASK) - 1 == 0 and int(g.pool_owner[r * S1]) == 1
        got[(0, *node)] = sim.slots.grad0[r].double()
        got[(1, *node)] = g._vel[g.n_nodes + r * S1].double()
    for (k, node), value in at.items():
        if value == eps:
            assert torch.equal(got[(k, *node)], torch.zeros(3, dtype=torch.float64)), (k, node)
        else:
            assert float(want[(k, *node)].abs().max()) > 0.1 * sim.node_mass * SHAPE[0], (k, node)
    scale = float(want.abs().max())
    assert float((got - want).abs().max()) <= 1e-5 * scale
