"""Boundaries (`sim.boundary`) on hand-placed points: a moving cuboid is where its corners at its start time
plus its velocity times the time since then put it, and a timed particle region acts on exactly the particles
inside its box on all three axes."""

import torch
import warp as wp

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.clock import FrameClock
from fracture_gs.sim.physics.boundary import apply_particle_region, cuboid_velocity

ensure_warp()


@wp.kernel
def _cuboid(xi: wp.array(dtype=wp.vec3), t: float, out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out[i] = cuboid_velocity(
        wp.vec3(0.0, 0.0, -1.0),
        xi[i],
        t,
        wp.vec3(0.0, 0.0, 0.0),
        wp.vec3(1.0, 1.0, 1.0),
        wp.vec3(1.0, 0.0, 0.0),
        wp.vec2(1.0, 3.0),
        wp.vec3(0.0, 0.0, 0.0),
    )


def test_a_moving_cuboid_is_displaced_by_its_velocity_times_the_time_since_it_started():
    """A sticky cuboid [0, 1]³ at its start time t₀ = 1 s, moving at (1, 0, 0) m/s, spans x ∈ [1, 2] at
    t = 2 s: a node at x = 1.5 takes the box's velocity, a node at x = 0.5 (inside the box's start position,
    left behind) and one at x = 3.5 (where t₀ + t instead of t − t₀ would put it) keep their own."""
    xi = wp.from_torch(torch.tensor([[1.5, 0.5, 0.5], [0.5, 0.5, 0.5], [3.5, 0.5, 0.5]]), dtype=wp.vec3)
    out = wp.zeros(3, dtype=wp.vec3, device="cpu")
    wp.launch(_cuboid, dim=3, inputs=[xi, 2.0, out], device="cpu")
    assert out.numpy().tolist() == [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 0.0, -1.0]]


def test_a_particle_region_tests_each_axis_against_its_own_bounds():
    """A velocity region over [0, 1] × [0, 1] × [0.5, 1] sets (1, 2, 3) on a particle at (0.5, 0.2, 0.7)
    (inside) and leaves one at (0.5, 0.7, 0.2) alone: its z is below the box although its y exceeds the lower
    z bound."""
    c = FrameClock("cpu", 1)
    c.set(1e-3, [0.0], on=[[1]], value=[[(1.0, 2.0, 3.0)]])
    x = wp.from_torch(torch.tensor([[0.5, 0.2, 0.7], [0.5, 0.7, 0.2]]), dtype=wp.vec3)
    v = wp.zeros(2, dtype=wp.vec3, device="cpu")
    lo, hi = wp.vec3(0.0, 0.0, 0.5), wp.vec3(1.0, 1.0, 1.0)
    wp.launch(apply_particle_region, dim=2, inputs=[x, v, lo, hi, 1, 0, c.view], device="cpu")
    assert v.numpy().tolist() == [[1.0, 2.0, 3.0], [0.0, 0.0, 0.0]]
