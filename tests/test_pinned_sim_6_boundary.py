"""Grid-side colliders (`sim.physics.boundary`) on single nodes, against hand-computed values:

- a moving cuboid acts on the nodes inside it, its six faces included, and on no node one step outside any face;
  each axis is tested against its own bounds (a box whose ranges differ per axis, so reading another axis's
  coordinate puts the inside out); it acts from its start time to its end time, both included;
- a kinematic sphere leaves nodes on or outside its surface alone, and at its very centre (no outward normal)
  takes the normal along its velocity, or +z when it is at rest: the answer is finite and exact there.

Coordinates are powers of two, so float32 holds them exactly and the faces are hit exactly."""

import torch
import warp as wp

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.physics.boundary import cuboid_velocity, sphere_velocity

ensure_warp()

LOWER, UPPER = (0.125, 0.5, 0.25), (0.25, 0.625, 0.375)  # x, y and z ranges that do not overlap
BOX_V = (0.5, 0.0, 0.0)  # the box's velocity (a sticky box gives it to the nodes inside)
NODE_V = (1.0, -1.0, 0.5)  # every node's velocity before the collider


@wp.kernel
def _cuboid(
    xi: wp.array(dtype=wp.vec3),
    t: float,
    v: wp.vec3,
    lower: wp.vec3,
    upper: wp.vec3,
    vb: wp.vec3,
    out: wp.array(dtype=wp.vec3),
):
    i = wp.tid()
    out[i] = cuboid_velocity(v, xi[i], t, lower, upper, vb, wp.vec2(1.0, 2.0), wp.vec3(0.0, 0.0, 0.0))


def _cuboid_at(points, t):
    xi = wp.from_torch(torch.tensor(points, dtype=torch.float32), dtype=wp.vec3)
    out = wp.zeros(len(points), dtype=wp.vec3, device="cpu")
    wp.launch(
        _cuboid,
        dim=len(points),
        inputs=[xi, float(t), wp.vec3(*NODE_V), wp.vec3(*LOWER), wp.vec3(*UPPER), wp.vec3(*BOX_V), out],
        device="cpu",
    )
    return [tuple(v) for v in out.numpy().tolist()]


def test_a_cuboid_holds_its_faces_and_nothing_one_step_beyond_on_every_axis():
    """A sticky box [1/8, 1/4] × [1/2, 5/8] × [1/4, 3/8] at its start time: its centre and a node on each of its six
    faces take the box's velocity (the faces are inside); a node 1/64 beyond any one face keeps its own."""
    centre = [(lo + hi) / 2 for lo, hi in zip(LOWER, UPPER)]
    inside, outside = [centre], []
    for a in range(3):
        for face, step in ((LOWER[a], -1 / 64), (UPPER[a], 1 / 64)):
            on = list(centre)
            on[a] = face
            inside.append(on)
            off = list(centre)
            off[a] = face + step
            outside.append(off)
    assert _cuboid_at(inside, 1.0) == [BOX_V] * 7
    assert _cuboid_at(outside, 1.0) == [NODE_V] * 6


def test_a_cuboid_acts_from_its_start_to_its_end_time_both_included():
    """Active for 1 s ≤ t ≤ 2 s, displaced by its velocity times t − 1 s: at t = 2 s the box spans x ∈ [5/8, 3/4]
    and grips a node there; at t = 1 s it grips the node at its start position. Just before the start
    (t = 1 − 2⁻¹⁰ s, where the box still overlaps the node) and just after the end, the node keeps its velocity."""
    y, z = 0.5625, 0.3125
    assert _cuboid_at([(0.6875, y, z)], 2.0) == [BOX_V]
    assert _cuboid_at([(0.1875, y, z)], 1.0) == [BOX_V]
    assert _cuboid_at([(0.1875, y, z)], 1.0 - 2**-10) == [NODE_V]
    assert _cuboid_at([(0.6875, y, z)], 2.0 + 2**-10) == [NODE_V]


@wp.kernel
def _sphere(v: wp.array(dtype=wp.vec3), xi: wp.array(dtype=wp.vec3), vs: wp.vec3, out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out[i] = sphere_velocity(v[i], xi[i], 0.0, wp.vec3(0.5, 0.5, 0.5), 0.25, vs, wp.vec2(0.0, 1.0))


def _sphere_at(v, x, vs):
    vw = wp.from_torch(torch.tensor(v, dtype=torch.float32), dtype=wp.vec3)
    xw = wp.from_torch(torch.tensor(x, dtype=torch.float32), dtype=wp.vec3)
    out = wp.zeros(len(v), dtype=wp.vec3, device="cpu")
    wp.launch(_sphere, dim=len(v), inputs=[vw, xw, wp.vec3(*vs), out], device="cpu")
    return [tuple(a) for a in out.numpy().tolist()]


def test_a_sphere_at_its_centre_pushes_along_its_velocity_and_leaves_its_surface_alone():
    """Ball of radius 1/4 at (1/2, 1/2, 1/2). At the centre (r = 0) the normal is v_s/|v_s|: with v_s = (0, 2, 0) a
    node moving (0, −1, 0.25) has v_rel·n = −3 and becomes (0, 2, 0.25), one moving (0, 3, 0) is left alone; a ball
    at rest takes n = +z there, (0.25, 0.125, −0.5) → (0.25, 0.125, 0). A node exactly on the surface (r = radius) is
    outside and keeps an approaching velocity; one 1/128 inside it along −x loses the approach."""
    centre = (0.5, 0.5, 0.5)
    got = _sphere_at([(0.0, -1.0, 0.25), (0.0, 3.0, 0.0)], [centre, centre], (0.0, 2.0, 0.0))
    assert got == [(0.0, 2.0, 0.25), (0.0, 3.0, 0.0)]
    assert _sphere_at([(0.25, 0.125, -0.5)], [centre], (0.0, 0.0, 0.0)) == [(0.25, 0.125, 0.0)]
    approach = (0.5, 0.25, 0.0)  # moving +x toward a node's outward normal −x
    got = _sphere_at([approach, approach], [(0.25, 0.5, 0.5), (0.25 + 1 / 128, 0.5, 0.5)], (0.0, 0.0, 0.0))
    assert got == [approach, (0.0, 0.25, 0.0)]
