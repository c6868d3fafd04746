"""A plane collider on single grid nodes (`sim.physics.boundary.plane_velocity`), against hand values:

- it acts on nodes behind the plane only ((x_i − point)·n < 0); a node on the plane or in front keeps its velocity;
- sticky stops the node; slip removes the approaching normal part and keeps a separating one;
- Coulomb friction removes the approaching normal part v_n and shrinks the tangential part by μ|v_n|, to exactly
  zero when μ|v_n| ≥ |v_t| (static friction holds it), never reversing it;
- friction with μ = 0 is slip, bitwise, for any tangential velocity — however small: even one whose square
  underflows in float32 (|v_t|² = 0) is kept, not zeroed or turned into NaN by a 0/0.

The plane y = 0.5 with normal +y; nodes at y = 0.25 (behind), 0.5 (on it) and 0.75 (in front)."""

import torch
import warp as wp

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.physics.boundary import PLANE_MODE_IDS, plane_velocity

ensure_warp()

BEHIND, ON, FRONT = (0.0, 0.25, 0.0), (0.0, 0.5, 0.0), (0.0, 0.75, 0.0)


@wp.kernel
def _plane(v: wp.array(dtype=wp.vec3), xi: wp.array(dtype=wp.vec3), mode: int, mu: float, out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out[i] = plane_velocity(v[i], xi[i], wp.vec3(0.0, 0.5, 0.0), wp.vec3(0.0, 1.0, 0.0), mode, mu)


def _after(cases, mode, mu=0.0):
    """[(node, velocity)] → the velocities after the plane in `mode` with friction μ."""
    v = wp.from_torch(torch.tensor([c[1] for c in cases], dtype=torch.float32), dtype=wp.vec3)
    xi = wp.from_torch(torch.tensor([c[0] for c in cases], dtype=torch.float32), dtype=wp.vec3)
    out = wp.zeros(len(cases), dtype=wp.vec3, device="cpu")
    wp.launch(_plane, dim=len(cases), inputs=[v, xi, PLANE_MODE_IDS[mode], float(mu), out], device="cpu")
    return [tuple(p) for p in out.numpy().tolist()]


def test_nodes_on_or_in_front_of_the_plane_are_left_alone_in_every_mode():
    """A node on the plane and one in front keep an approaching velocity (2, −1, 0.5) in all three modes."""
    cases = [(ON, (2.0, -1.0, 0.5)), (FRONT, (2.0, -1.0, 0.5))]
    for mode in ("sticky", "slip", "friction"):
        assert _after(cases, mode, 0.5) == [(2.0, -1.0, 0.5)] * 2, mode


def test_sticky_stops_and_slip_removes_only_an_approaching_normal_part():
    """Behind the plane: sticky gives 0 for any velocity; slip turns (2, −1, 0.5) into (2, 0, 0.5) and keeps a
    separating (2, 1, 0.5)."""
    cases = [(BEHIND, (2.0, -1.0, 0.5)), (BEHIND, (2.0, 1.0, 0.5))]
    assert _after(cases, "sticky") == [(0.0, 0.0, 0.0)] * 2
    assert _after(cases, "slip") == [(2.0, 0.0, 0.5), (2.0, 1.0, 0.5)]


def test_coulomb_friction_shrinks_the_tangential_part_by_mu_times_the_normal_speed():
    """μ = 0.5, v_n = −1 (μ|v_n| = 0.5): |v_t| = 2 → 1.5 along the same direction; |v_t| = 0.5 → exactly 0 (the
    cone's edge); |v_t| = 0.25 → 0, not reversed; a separating node (v_n = +1) keeps everything; a node moving
    straight into the plane (v_t = 0) stops, finite."""
    cases = [
        (BEHIND, (2.0, -1.0, 0.0)),
        (BEHIND, (0.0, -1.0, -0.5)),
        (BEHIND, (0.25, -1.0, 0.0)),
        (BEHIND, (2.0, 1.0, 0.0)),
        (BEHIND, (0.0, -1.0, 0.0)),
    ]
    got = _after(cases, "friction", 0.5)
    assert got == [(1.5, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (2.0, 1.0, 0.0), (0.0, 0.0, 0.0)]


def test_frictionless_friction_is_slip_even_for_a_vanishing_tangential_speed():
    """μ = 0 gives slip's answer bitwise: v_t = (1e−24, 0, 0), whose square underflows in float32 (|v_t| = 0), is
    kept; v_t = 0 stays 0 (no 0/0); an ordinary (2, −1, 0.5) loses its normal part only."""
    tiny = float(torch.tensor(1e-24, dtype=torch.float32))
    assert float(torch.tensor(tiny, dtype=torch.float32) ** 2) == 0.0
    cases = [(BEHIND, (tiny, -1.0, 0.0)), (BEHIND, (0.0, -1.0, 0.0)), (BEHIND, (2.0, -1.0, 0.5))]
    want = [(tiny, 0.0, 0.0), (0.0, 0.0, 0.0), (2.0, 0.0, 0.5)]
    assert _after(cases, "slip") == want
    assert _after(cases, "friction", 0.0) == want
