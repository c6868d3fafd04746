"""Each axis of the slot storage's transfer kernels (`sim.grid.kernels`) uses its OWN bound or origin component,
on boxes whose six bounds all differ (a cube hides an axis that reads another axis's value):

- P2G counts a particle as escaped when its 3×3×3 stencil leaves the active box [lo, hi) through any one of the
  six faces, and not when the stencil touches a face from inside (`stencil.inside`);
- G2P clamps each coordinate of x + Δt v into [lower, upper] of that axis, exactly onto the bound, and counts
  a clamped particle once (`stencil.finish_g2p`);
- the dense grid update, launched over an active box, writes exactly the nodes of that box, offset on each axis
  by that axis's own origin component (`grid_update_dense`).

Grids of 8³-9³ nodes at Δx = 1/8 on the CPU; positions and velocities are exact in float32."""

import pytest
import torch
import warp as wp

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.clock import FrameClock
from fracture_gs.sim.grid.fields import Grid
from fracture_gs.sim.grid.kernels import g2p, grid_update_dense, p2g
from fracture_gs.sim.physics.boundary import Boundaries
from fracture_gs.sim.storage import COUNT_CLAMPED, COUNT_ESCAPED, N_COUNTS

ensure_warp()
DX = 1 / 8


def _clock(dt):
    c = FrameClock("cpu", 0)
    c.set(dt, [0.0])
    return c


def _escapes(base, lo, hi):
    """COUNT_ESCAPED after one single-field P2G of one particle at rest whose stencil base is `base` (placed at
    the stencil's centre node, x = (base + 1) Δx), on a 9³ grid with active box [lo, hi)."""
    g = Grid((0.0, 0.0, 0.0), DX, (9, 9, 9), "cpu")
    x = (torch.tensor([base], dtype=torch.float64) + 1.0) * DX
    counts = torch.zeros(N_COUNTS, dtype=torch.int32)
    z3, z33 = torch.zeros(1, 3), torch.zeros(1, 3, 3)
    inputs = [wp.from_torch(x.float(), dtype=wp.vec3), wp.from_torch(z3, dtype=wp.vec3)]
    inputs += [wp.from_torch(z33, dtype=wp.mat33), wp.from_torch(torch.ones(1)), wp.from_torch(torch.full((1,), 1e-3))]
    inputs += [wp.from_torch(z33.clone(), dtype=wp.mat33)]
    inputs += [wp.from_torch(torch.zeros(1, dtype=torch.int32)) for _ in range(3)]  # fragment, band, solo
    inputs += [0, -1, 0, _clock(1e-3).view, g.view, wp.vec3i(*lo), wp.vec3i(*hi), wp.from_torch(counts)]
    wp.launch(p2g, dim=1, inputs=inputs, device="cpu")
    assert abs(float(g.mp[..., 3].sum()) - 1.0) < 1e-5, "the deposit lands whether or not it escaped"
    return int(counts[COUNT_ESCAPED])


LO, HI = (1, 2, 3), (8, 6, 7)  # stencil bases inside: x ∈ [1, 5], y ∈ [2, 3], z ∈ [3, 4]


@pytest.mark.parametrize(
    "base,escaped",
    [
        ((1, 2, 3), 0),  # touches the three lower faces from inside
        ((5, 3, 4), 0),  # touches the three upper faces from inside (nodes 7, 5, 6)
        ((0, 2, 3), 1),  # one node below x = 1
        ((6, 3, 4), 1),  # node 8 = hi[0] on x
        ((1, 1, 3), 1),  # one node below y = 2
        ((5, 4, 4), 1),  # node 6 = hi[1] on y
        ((1, 2, 2), 1),  # one node below z = 3
        ((5, 3, 5), 1),  # node 7 = hi[2] on z
        ((0, 4, 5), 1),  # three faces at once: still one escape
    ],
)
def test_p2g_counts_an_escape_through_each_face_of_an_uneven_active_box(base, escaped):
    """Active box [1, 8) × [2, 6) × [3, 7): a stencil (nodes base … base + 2) is inside iff lo ≤ base and base + 2
    < hi on every axis; leaving through any single face, by one node, counts one escape, and a stencil that
    touches a face from inside counts none."""
    assert _escapes(base, LO, HI) == escaped


def _g2p(u, x, lower, upper, dt=0.25):
    """One single-field G2P on an 8³ grid whose slot-0 velocity is u everywhere; returns (x, v, clamped count)."""
    g = Grid((0.0, 0.0, 0.0), DX, (8, 8, 8), "cpu")
    g._vel.copy_(torch.tensor(u).expand(g._vel.shape[0], 3))
    n = len(x)
    x = torch.tensor(x, dtype=torch.float32)
    v, C, F = torch.zeros(n, 3), torch.zeros(n, 3, 3), torch.eye(3).repeat(n, 1, 1)
    ints = [wp.from_torch(torch.zeros(n, dtype=torch.int32)) for _ in range(2)]  # fragment, solo
    counts = torch.zeros(N_COUNTS, dtype=torch.int32)
    inputs = [wp.from_torch(x, dtype=wp.vec3), wp.from_torch(v, dtype=wp.vec3), wp.from_torch(C, dtype=wp.mat33)]
    inputs += [wp.from_torch(F, dtype=wp.mat33)] + ints
    inputs += [wp.from_torch(torch.arange(n, dtype=torch.int32)), wp.from_torch(torch.tensor([0], dtype=torch.int32))]
    inputs += [0, 0, wp.zeros(1, dtype=wp.int32, device="cpu"), 0, 0, -1, _clock(dt).view, g.view]
    inputs += [wp.vec3(*lower), wp.vec3(*upper), wp.from_torch(counts)]
    wp.launch(g2p, dim=n, inputs=inputs, device="cpu")
    return x, v, int(counts[COUNT_CLAMPED])


def test_g2p_clamps_each_coordinate_onto_its_own_axis_bound():
    """Uniform grid velocity ±(1, 1, 1) m/s, Δt = 0.25 s: a particle at 0.5 moves to 0.75 (or 0.25) on every axis,
    past three different upper bounds (0.6, 0.65, 0.7) or lower bounds (0.4, 0.35, 0.3), and lands exactly on each
    axis's own bound; a particle at 0.25 (or 0.75) moves to 0.5, inside, untouched. One clamped particle
    counts once, whatever the number of its clamped axes; both take the grid's velocity."""
    f32 = lambda *a: torch.tensor(a, dtype=torch.float32)  # noqa: E731
    x, v, clamped = _g2p((1.0, 1.0, 1.0), [(0.5, 0.5, 0.5), (0.25, 0.25, 0.25)], (0.1, 0.2, 0.25), (0.6, 0.65, 0.7))
    assert torch.equal(x[0], f32(0.6, 0.65, 0.7)) and torch.equal(x[1], f32(0.5, 0.5, 0.5))
    assert clamped == 1
    assert torch.allclose(v, torch.ones(2, 3), rtol=0, atol=1e-6)
    x, v, clamped = _g2p((-1.0, -1.0, -1.0), [(0.5, 0.5, 0.5), (0.75, 0.75, 0.75)], (0.4, 0.35, 0.3), (0.9, 0.85, 0.8))
    assert torch.equal(x[0], f32(0.4, 0.35, 0.3)) and torch.equal(x[1], f32(0.5, 0.5, 0.5))
    assert clamped == 1
    assert torch.allclose(v, -torch.ones(2, 3), rtol=0, atol=1e-6)


def test_g2p_clamps_a_single_axis_and_leaves_the_others():
    """Velocity (1, 1, 1), Δt = 0.25, from 0.5: only the y bound (0.7 < 0.75) binds; x and z bounds at 0.8 and 0.9
    do not, so x = (0.75, 0.7, 0.75), counted once. With y's bound raised to 0.75 exactly, nothing is clamped
    (the bound itself is inside) and nothing is counted."""
    x, _, clamped = _g2p((1.0, 1.0, 1.0), [(0.5, 0.5, 0.5)], (0.0, 0.0, 0.0), (0.8, 0.7, 0.9))
    assert torch.equal(x[0], torch.tensor([0.75, 0.7, 0.75])) and clamped == 1
    x, _, clamped = _g2p((1.0, 1.0, 1.0), [(0.5, 0.5, 0.5)], (0.0, 0.0, 0.0), (0.8, 0.75, 0.9))
    assert x[0].tolist() == [0.75, 0.75, 0.75] and clamped == 0


def test_the_dense_grid_update_writes_exactly_the_launched_box():
    """An 8³ grid with m = 2, p = (2, 4, −6) at every node (v = p/m = (1, 2, −3), no gravity, no walls), velocities
    preset to 7: a 3 × 2 × 4 launch at box origin (1, 4, 2) writes (1, 2, −3) at nodes [1, 4) × [4, 6) × [2, 6) and
    no other node."""
    g = Grid((0.0, 0.0, 0.0), DX, (8, 8, 8), "cpu")
    g.mp[:] = torch.tensor([2.0, 4.0, -6.0, 2.0])
    g.vel.fill_(7.0)
    colliders = Boundaries([], "cpu", (8, 8, 8), 0).colliders
    inputs = [g.view, wp.vec3i(1, 4, 2), 0, 1e-3, _clock(1e-3).view, wp.vec3(0.0, 0.0, 0.0), colliders]
    wp.launch(grid_update_dense, (3, 2, 4), inputs, device="cpu")
    want = torch.full((8, 8, 8, 3), 7.0)
    want[1:4, 4:6, 2:6] = torch.tensor([1.0, 2.0, -3.0])
    assert torch.equal(g.vel, want)
