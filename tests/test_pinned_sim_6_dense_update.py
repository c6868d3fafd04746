"""The slot storage's dense grid update (`grid.kernels.grid_update_dense`) on a one-field grid filled by hand:
every node with m > ε_m gets v = p/m + Δt g, and the colliders then see it at its world position
x_i = origin + (i, j, l)·Δx, each axis from its own index, the grid's origin included; a node at or below ε_m is 0.
A sticky plane across each axis in turn zeroes exactly the nodes behind it along that axis. A 6 × 7 × 8 grid with
a different origin per axis, so that an index or origin read from the wrong axis moves the plane's cut."""

import pytest
import torch
import warp as wp

from fracture_gs.config import PlaneBoundary
from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.clock import FrameClock
from fracture_gs.sim.grid.fields import Grid
from fracture_gs.sim.grid.kernels import grid_update_dense
from fracture_gs.sim.physics.boundary import Boundaries

SHAPE, ORIGIN, DX, DT, EPS = (6, 7, 8), (0.25, -0.5, 1.0), 0.125, 1e-3, 1e-4
GRAVITY = (0.0, 0.0, -9.81)


def _update(plane):
    """The grid's velocities [X, Y, Z, 3] after the dense update with `plane`, and the expected free velocity."""
    ensure_warp()
    g = Grid(ORIGIN, DX, SHAPE, "cpu")
    gen = torch.Generator().manual_seed(2)
    m = 0.5 + torch.rand(SHAPE, generator=gen)
    m[1, 2, 3] = 0.5 * EPS  # a node holding less than ε_m
    p = torch.randn(*SHAPE, 3, generator=gen)
    g.mp.copy_(torch.cat([p, m[..., None]], -1))
    clock = FrameClock("cpu", 0)
    clock.set(DT, [0.0])
    colliders = Boundaries([plane], "cpu", SHAPE, 0).colliders
    inputs = [g.view, wp.vec3i(0, 0, 0), 0, EPS, clock.view, wp.vec3(*GRAVITY), colliders]
    wp.launch(grid_update_dense, SHAPE, inputs, device="cpu")
    free = p.double() / m.double()[..., None] + DT * torch.tensor(GRAVITY, dtype=torch.float64)
    free[1, 2, 3] = 0.0
    return g.vel.double().clone(), free


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_a_sticky_plane_cuts_the_grid_at_its_world_position_along_each_axis(axis):
    """A sticky plane with normal +e_a through origin_a + 2.5Δx: nodes of index 0, 1, 2 along axis a lie behind it
    and stop (v = 0); every other node keeps p/m + Δt g (float32 rounding); the node below ε_m is 0."""
    point = [0.0, 0.0, 0.0]
    point[axis] = ORIGIN[axis] + 2.5 * DX
    normal = [0.0, 0.0, 0.0]
    normal[axis] = 1.0
    vel, free = _update(PlaneBoundary(point=tuple(point), normal=tuple(normal), mode="sticky"))
    behind = torch.zeros(SHAPE, dtype=torch.bool)
    behind.index_fill_(axis, torch.arange(3), True)
    assert float(vel[behind].abs().max()) == 0.0, "every node behind the plane stops"
    ahead = ~behind
    torch.testing.assert_close(vel[ahead], free[ahead], rtol=1e-5, atol=1e-6)
