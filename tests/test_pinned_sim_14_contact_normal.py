"""The contact normal between two fields at a node (`sim.physics.contact.contact_normal`), from field a (fragment
k_a) into field b (fragment k_b):

- with the latched normal mode it is the first event's plane normal, whatever the fields' mass gradients;
- with mass-gradient normals it is the unit (∇m_b − ∇m_a), as long as that difference stands out of rounding
  (|∇m_b − ∇m_a| > 10⁻⁶ (|∇m_a| + |∇m_b|));
- where it does not (no gradients, or equal ones) it points from fragment a's centroid to fragment b's (swapping
  the fragments reverses it), and where those coincide too it is the latched normal: always a unit vector.

Values are exact in float32 (3-4-5 triangles, axis directions)."""

import torch
import warp as wp

from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.physics.contact import NORMAL_LATCHED, NORMAL_MASS_GRADIENT, contact_normal

ensure_warp()

LATCHED = (0.6, 0.0, 0.8)
CENTROIDS = [(1.0, 0.0, 0.0), (1.0, 2.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 3.0), (5.0, 5.0, 5.0), (5.0, 5.0, 5.0)]


@wp.kernel
def _normal(
    mode: wp.array(dtype=int),
    g: wp.array(dtype=wp.vec3),  # [2 × cases] ∇m_a, ∇m_b
    k: wp.array(dtype=int),  # [2 × cases] k_a, k_b
    centroids: wp.array(dtype=wp.vec3),
    out: wp.array(dtype=wp.vec3),
):
    i = wp.tid()
    latched = wp.vec3(0.6, 0.0, 0.8)
    out[i] = contact_normal(mode[i], latched, g[2 * i], g[2 * i + 1], centroids, k[2 * i], k[2 * i + 1])


def _normals(cases):
    """[(mode, ∇m_a, ∇m_b, k_a, k_b)] → the normals."""
    mode = wp.array([c[0] for c in cases], dtype=int, device="cpu")
    g = wp.from_torch(torch.tensor([v for c in cases for v in c[1:3]], dtype=torch.float32), dtype=wp.vec3)
    k = wp.array([v for c in cases for v in c[3:5]], dtype=int, device="cpu")
    cen = wp.from_torch(torch.tensor(CENTROIDS, dtype=torch.float32), dtype=wp.vec3)
    out = wp.zeros(len(cases), dtype=wp.vec3, device="cpu")
    wp.launch(_normal, dim=len(cases), inputs=[mode, g, k, cen, out], device="cpu")
    return [tuple(p) for p in out.numpy().tolist()]


def _f32(*vectors):
    """The vectors as float32 holds them (0.6 and 0.8 are not exact)."""
    return [tuple(torch.tensor(v, dtype=torch.float32).tolist()) for v in vectors]


def test_the_latched_mode_ignores_the_gradients():
    """NORMAL_LATCHED: (0.6, 0, 0.8) with gradients (0, 3, 4) vs 0 and with none at all."""
    zero = (0.0, 0.0, 0.0)
    got = _normals([(NORMAL_LATCHED, zero, (0.0, 3.0, 4.0), 0, 1), (NORMAL_LATCHED, zero, zero, 0, 1)])
    assert got == _f32(LATCHED, LATCHED)


def test_mass_gradient_normals_point_along_the_gradient_difference():
    """∇m_b − ∇m_a = (0, 3, 4) − 0 → (0, 0.6, 0.8); (1, 1, 0) − (1, −2, −4) = (0, 3, 4) → the same; swapped, −."""
    got = _normals(
        [
            (NORMAL_MASS_GRADIENT, (0.0, 0.0, 0.0), (0.0, 3.0, 4.0), 0, 1),
            (NORMAL_MASS_GRADIENT, (1.0, -2.0, -4.0), (1.0, 1.0, 0.0), 0, 1),
            (NORMAL_MASS_GRADIENT, (0.0, 3.0, 4.0), (0.0, 0.0, 0.0), 1, 0),
        ]
    )
    assert got == _f32((0.0, 0.6, 0.8), (0.0, 0.6, 0.8), (0.0, -0.6, -0.8))


def test_degenerate_gradients_fall_back_to_the_centroids_then_to_the_latched_normal():
    """No gradients: fragment 0 → 1 is centroid (1, 2, 0) − (1, 0, 0) → (0, 1, 0), 1 → 0 the reverse; equal
    gradients (2, 2, 2): fragment 2 → 3 along (0, 0, 3) → +z; a difference 0.001 under 10⁻⁶ · 2000 counts as none
    (+z from the centroids), 0.004 above it gives its own direction (0, 1, 0); coinciding centroids (4, 5) and no
    gradients: the latched normal."""
    zero = (0.0, 0.0, 0.0)
    got = _normals(
        [
            (NORMAL_MASS_GRADIENT, zero, zero, 0, 1),
            (NORMAL_MASS_GRADIENT, zero, zero, 1, 0),
            (NORMAL_MASS_GRADIENT, (2.0, 2.0, 2.0), (2.0, 2.0, 2.0), 2, 3),
            (NORMAL_MASS_GRADIENT, (1000.0, 0.0, 0.0), (1000.0, 0.001, 0.0), 2, 3),
            (NORMAL_MASS_GRADIENT, (1000.0, 0.0, 0.0), (1000.0, 0.004, 0.0), 2, 3),
            (NORMAL_MASS_GRADIENT, zero, zero, 4, 5),
        ]
    )
    assert got == _f32((0.0, 1.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, 1.0), (0.0, 0.0, 1.0), (0.0, 1.0, 0.0), LATCHED)
