"""Both grid-update passes of the slot storage (`sim.grid.kernels.grid_update_dense`, `grid_update_pool`) apply
the boundaries at each node's own position x_i = origin + (i, j, l)·Δx — the pool pass recovers (i, j, l) from
the row's flat node index (`stencil.unflat`) — so a sticky plane stops exactly the fields at nodes behind it.

A 6 × 7 × 8 grid (no axis the same length, so a wrong unflat shows) at an origin off zero by a different amount
on each axis, Δx = 1/8, and an oblique sticky plane with normal (1, 2, −3)/√14 moved until no node lies within
10⁻³ Δx of it. No gravity, no contact: a field keeps v = p/m in front of the plane and gets 0 behind it."""

import torch
import warp as wp
from simutil import fill_slots

from fracture_gs.config import PlaneBoundary
from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.clock import FrameClock
from fracture_gs.sim.grid.fields import Grid
from fracture_gs.sim.grid.kernels import grid_update_dense, grid_update_pool
from fracture_gs.sim.physics.boundary import Boundaries
from fracture_gs.sim.physics.contact import NORMAL_LATCHED

ensure_warp()
SHAPE, DX, EPS = (6, 7, 8), 1 / 8, 1e-3
ORIGIN = (0.3, -0.2, 0.15)
V0, V1 = (1.0, -0.5, 0.25), (-2.0, 0.75, 1.5)


def _plane():
    normal = torch.tensor([1.0, 2.0, -3.0], dtype=torch.float64) / 14**0.5
    point = torch.tensor(ORIGIN, dtype=torch.float64) + torch.tensor([0.31, 0.43, 0.52], dtype=torch.float64)
    idx = torch.stack(torch.meshgrid(*[torch.arange(s) for s in SHAPE], indexing="ij"), -1).double()
    xi = torch.tensor(ORIGIN, dtype=torch.float64) + idx * DX
    while bool((((xi - point) @ normal).abs() < 1e-3 * DX).any()):
        point = point + 1e-2 * DX * normal
    behind = (xi - point) @ normal < 0  # [X, Y, Z]
    assert 0.2 < float(behind.double().mean()) < 0.8, "nodes on both sides"
    walls = Boundaries([PlaneBoundary(point=tuple(point.tolist()), normal=tuple(normal.tolist()), mode="sticky")],
                       "cpu", SHAPE, 0)  # fmt: skip
    return walls, behind


def _clock():
    c = FrameClock("cpu", 0)
    c.set(1e-3, [0.0])
    return c


def _want(v, behind):
    want = torch.tensor(v).expand(*SHAPE, 3).clone()
    want[behind] = 0.0
    return want


def test_the_dense_pass_stops_exactly_the_nodes_behind_the_plane():
    """One field, m = 2, p = 2 V0 at every node: V0 in front of the plane, 0 behind it."""
    walls, behind = _plane()
    g = Grid(ORIGIN, DX, SHAPE, "cpu")
    g.mp[:] = torch.tensor([2 * V0[0], 2 * V0[1], 2 * V0[2], 2.0])
    inputs = [g.view, wp.vec3i(0, 0, 0), 0, EPS, _clock().view, wp.vec3(0.0, 0.0, 0.0), walls.colliders]
    wp.launch(grid_update_dense, SHAPE, inputs, device="cpu")
    assert torch.equal(g.vel, _want(V0, behind))


def test_the_pool_pass_stops_both_fields_exactly_at_the_nodes_behind_the_plane():
    """Two fields at every node (fragment 0 in slot 0 at V0, fragment 1 in the pool slot at V1, m = 1 each), every
    node with a row, the contact gate off: each field keeps its velocity in front of the plane and gets 0 behind."""
    walls, behind = _plane()
    g = Grid(ORIGIN, DX, SHAPE, "cpu", slots=2)
    n = g.n_nodes
    g.ensure_pool(n)
    m = torch.ones(2, *SHAPE, dtype=torch.float64)
    v = torch.stack([torch.tensor(V0).expand(*SHAPE, 3), torch.tensor(V1).expand(*SHAPE, 3)]).double()
    fill_slots(g, m, v)
    cen = wp.zeros(2, dtype=wp.vec3, device="cpu")
    grad0 = wp.zeros(g.capacity, dtype=wp.vec3, device="cpu")
    inputs = [g.view, EPS, 0.0, 0.0, 0, 1, NORMAL_LATCHED, wp.vec3(0.0, 0.0, 1.0), cen, 0.0, 0.0]
    inputs += [_clock().view, wp.vec3(0.0, 0.0, 0.0), walls.colliders, 0, g.wp["stats"], g.wp["pair_stats"], 2, grad0]
    wp.launch(grid_update_pool, dim=g.capacity, inputs=inputs, device="cpu")
    rows = torch.full((n,), -1, dtype=torch.long)
    used = torch.nonzero(g.key >= 0).flatten()
    rows[g.key[used].long()] = used
    assert bool((rows >= 0).all())
    assert torch.equal(g._vel[:n].view(*SHAPE, 3), _want(V0, behind))
    assert torch.equal(g._vel[n + rows].view(*SHAPE, 3), _want(V1, behind))
