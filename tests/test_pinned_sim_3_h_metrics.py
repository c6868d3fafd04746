"""`sim/metrics.py` pairings on hand-placed particles: the interface pairs join band particles of fragment 0 to
their nearest band particle of fragment 1 within the pair radius (particles outside the band never pair, on
either side), and the piece gap measures between the two largest pieces, where particles without a fragment
(id −1, before any event) are no piece at all. Distances are binary-exact so each bound is decided by the
comparison."""

import math

import torch

from fracture_gs.sim.diagnostics.metrics import interface_pairs, piece_gap


def _x(*rows):
    return torch.tensor(rows, dtype=torch.float32)


def _i(*v):
    return torch.tensor(v, dtype=torch.int32)


def test_interface_pairs_join_band_particles_to_their_nearest_partner_within_the_radius():
    """Fragment 0's band particles at x = 0 and 2 and a non-band one at x = 0.25; fragment 1's band
    particles at x = 0.5 and 2.25 and a non-band one at x = 0.125 (nearer to both of fragment 0's left
    particles). Radius 0.75: p = 0 pairs with q = 0.5 (the non-band 0.125 is no partner), p = 2 with 2.25;
    the non-band particle of fragment 0 pairs with nobody although a partner is within reach. A band tag
    of any event counts (tags 1 and 3). With radius 0.5 exactly, 0 → 0.5 is not within (strictly closer)."""
    x = _x([0.0, 0, 0], [2.0, 0, 0], [0.25, 0, 0], [0.5, 0, 0], [2.25, 0, 0], [0.125, 0, 0])
    fragment = _i(0, 0, 0, 1, 1, 1)
    band = _i(1, 3, 0, 1, 3, 0)
    p, q = interface_pairs(x, fragment, band, 0.75)
    assert sorted(zip(p.tolist(), q.tolist())) == [(0, 3), (1, 4)]
    p, q = interface_pairs(x, fragment, band, 0.5)
    assert list(zip(p.tolist(), q.tolist())) == [(1, 4)]


def test_interface_pairs_are_empty_without_band_particles_on_one_side():
    """No band particle in fragment 1 (or none in fragment 0): no pairs, as empty index tensors; particles
    of other fragments (2) never pair, whatever their band. Small chunks give the same pairs as one chunk."""
    x = _x([0.0, 0, 0], [0.25, 0, 0], [0.5, 0, 0], [0.75, 0, 0])
    p, q = interface_pairs(x, _i(0, 1, 2, 0), _i(1, 0, 1, 1), 1.0)
    assert p.numel() == 0 and q.numel() == 0
    p, q = interface_pairs(x, _i(0, 1, 2, 1), _i(0, 1, 1, 1), 1.0)
    assert p.numel() == 0 and q.numel() == 0
    fragment, band = _i(0, 1, 2, 0), _i(1, 1, 1, 1)
    one = interface_pairs(x, fragment, band, 1.0)
    small = interface_pairs(x, fragment, band, 1.0, chunk=1)
    assert [t.tolist() for t in one] == [t.tolist() for t in small] == [[0, 3], [1, 1]]


def test_piece_gap_ignores_particles_without_a_fragment():
    """Fragment 0 (8 particles, x ≤ 0.25), fragment 1 (4 particles, x ≥ 1) and 20 particles with no fragment
    yet (id −1) lying between them at x = 0.5, and a one-particle fragment 2 at x = 3: the gap is between the
    two largest pieces 0 and 1, 1 − 0.25 = 0.75 = 3 Δx for Δx = 0.25, not to the unlabelled particles (which
    would be the largest "piece") nor to the crumb. A lone fragment among unlabelled particles has no gap."""
    a = torch.stack(torch.meshgrid(*[torch.tensor([0.0, 0.25])] * 3, indexing="ij"), -1).reshape(-1, 3)
    b = _x([1.0, 0, 0], [1.0, 0.25, 0], [1.25, 0, 0], [1.25, 0.25, 0])
    loose = torch.zeros(20, 3) + torch.tensor([0.5, 0.0, 0.0])
    loose[:, 1] = torch.arange(20) * 0.25
    x = torch.cat([a, b, loose, _x([3.0, 0, 0])])
    frag = torch.cat([torch.zeros(8), torch.ones(4), torch.full((20,), -1), torch.full((1,), 2)]).to(torch.int32)
    assert math.isclose(piece_gap(x, frag, 0.25), 3.0, rel_tol=1e-12)
    frag[8:12] = -1
    frag[-1] = -1
    assert piece_gap(x, frag, 0.25) == 0.0
