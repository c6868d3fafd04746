"""The mass gradients of the contact normals (`sim.grid.normal_kernels.pool_mass_gradients`) over a whole grid
that is not a cube: at every node, for each of two fragments, ∂m/∂x_a = (m(i + e_a) − m(i − e_a)) / 2Δx, where a
neighbour past the grid reads the nearest node inside on that axis (replicate padding), so at a face the
difference is one-sided and halved. Each axis clamps to its own extent; the gradient of each field goes to its
own slot's buffer (slot 0: `grad0[row]`; the pool slot: its velocity entry).

A 5 × 7 × 6 grid (Δx = 1/4) with 2 slots; every node has a row (`simutil.fill_slots`). Fragment 0's mass is
1 + i + 2j² + 3l (slot 0), fragment 1's 10 + 4i² + j + l² (the pool slot): quadratic on some axes, so a wrong
neighbour on any axis changes the value."""

import torch
import warp as wp
from simutil import fill_slots

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.grid.fields import Grid
from fracture_gs.sim.grid.normal_kernels import pool_mass_gradients

SHAPE, DX, EPS = (5, 7, 6), 0.25, 1e-3


def _reference(m):
    """Central differences with replicate padding, float64 [X, Y, Z, 3]."""
    out = []
    for a in range(3):
        n = m.shape[a]
        up = m.index_select(a, torch.clamp(torch.arange(n) + 1, max=n - 1))
        down = m.index_select(a, torch.clamp(torch.arange(n) - 1, min=0))
        out.append((up - down) / (2 * DX))
    return torch.stack(out, -1)


def test_every_nodes_mass_gradient_uses_its_own_axis_extent_at_the_faces():
    """Both fragments' gradients at all 210 nodes equal the replicate-padded central differences (exact in
    float32: small integers over 2Δx = ½)."""
    ensure_warp()
    g = Grid((0.0, 0.0, 0.0), DX, SHAPE, "cpu", slots=2)
    n = g.n_nodes
    g.ensure_pool(n)
    i, j, l = torch.meshgrid(*[torch.arange(s, dtype=torch.float64) for s in SHAPE], indexing="ij")  # noqa: E741
    m = torch.stack([1 + i + 2 * j**2 + 3 * l, 10 + 4 * i**2 + j + l**2])
    fill_slots(g, m, torch.zeros(*m.shape, 3, dtype=torch.float64))
    g._vel.fill_(7.0)
    grad0 = torch.full((g.capacity, 3), 7.0)
    inputs = [g.view, EPS, wp.from_torch(grad0, dtype=wp.vec3)]
    wp.launch(pool_mass_gradients, g.capacity * g.slots, inputs, device="cpu")
    rows = torch.full((n,), -1, dtype=torch.long)
    used = torch.nonzero(g.key >= 0).flatten()
    rows[g.key[used].long()] = used
    assert bool((rows >= 0).all()), "every node has a row"
    got0 = grad0[rows].view(*SHAPE, 3).double()
    got1 = g._vel[n + rows].view(*SHAPE, 3).double()
    assert torch.equal(got0, _reference(m[0]))
    assert torch.equal(got1, _reference(m[1]))
