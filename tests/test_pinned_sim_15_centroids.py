"""`sim.neighbourhood.fragment_centroids` with real particle masses: a splat's particles weigh micrograms, so a
fragment's total mass is far below 1 kg and the centroid Σ m x / Σ m must not depend on the mass unit. Only an
empty fragment (Σ m = 0) is guarded, and it reads 0, not NaN."""

import torch

from fracture_gs.sim.neighbourhood import fragment_centroids


def test_centroids_of_microgram_fragments_are_their_mass_weighted_means():
    """Fragment 0: 1 µg at x = 1 and 3 µg at x = 3 → centroid x = (1 + 9)/4 = 2.5; fragment 1: two 10⁻¹² kg
    particles at (0, 2, 4) and (0, 4, 8) → (0, 3, 6); fragment 2 empty → 0. Scaling every mass by 10⁶ changes
    nothing (a centroid is scale-free in mass)."""
    x = torch.tensor([[1.0, 0.0, 0.0], [3.0, 0.0, 0.0], [0.0, 2.0, 4.0], [0.0, 4.0, 8.0]])
    m = torch.tensor([1e-9, 3e-9, 1e-12, 1e-12])
    frag = torch.tensor([0, 0, 1, 1], dtype=torch.int32)
    want = torch.tensor([[2.5, 0.0, 0.0], [0.0, 3.0, 6.0], [0.0, 0.0, 0.0]])
    for scale in (1.0, 1e6):
        c = fragment_centroids(x, m * scale, frag, 3)
        torch.testing.assert_close(c, want, rtol=1e-6, atol=0.0)
        assert bool(torch.isfinite(c).all())


def test_a_fragment_of_massless_particles_reads_zero():
    """Σ m = 0 (particles of zero mass) is the guarded case: the centroid is 0, not 0/0."""
    x = torch.tensor([[5.0, 5.0, 5.0], [1.0, 1.0, 1.0]])
    c = fragment_centroids(x, torch.tensor([0.0, 2e-9]), torch.tensor([0, 1], dtype=torch.int32), 2)
    assert c.tolist() == [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]
