"""The continuous penetration measure's calibration (`sim.penetration.calibrate`): each fragment id's filled
density is its number density, 1/h³ for a jittered grid of spacing h, found from positions alone; an id no
particle carries gets 1 (never the huge density its empty spacing would imply), and so do all ids when no
particle is labelled. Its cell binning (`_Cells.near_foreign`) marks exactly the particles with a particle of
another fragment in their cell or one of the 26 around it."""

import pytest
import torch
from test_penetration_resolution import stratified

from fracture_gs.sim.diagnostics.penetration import _Cells, calibrate


def test_filled_density_is_each_pieces_number_density_and_one_for_an_empty_id(one_thread):
    """Fragment 0 a jittered grid of h = 0.01, fragment 2 one of h = 0.008 beside it, id 1 unused: filled[0] is
    1/0.01³ and filled[2] 1/0.008³ within 5 %, filled[1] exactly 1; unlabelled particles (−1) change nothing.
    With no labelled particle the radius is 0 and the single entry 1."""
    g = torch.Generator().manual_seed(2)
    a = stratified((0.0, 0.0, 0.0), (0.1, 0.1, 0.1), 0.01, g)
    b = stratified((0.1, 0.0, 0.0), (0.2, 0.1, 0.1), 0.008, g)
    stray = stratified((0.0, 0.2, 0.0), (0.1, 0.3, 0.1), 0.02, g)
    x = torch.cat([a, b, stray]).float()
    frag = torch.cat([torch.zeros(len(a)), torch.full((len(b),), 2), torch.full((len(stray),), -1)]).int()
    c = calibrate(x, frag)
    filled = c["filled"]
    assert filled.shape == (3,) and filled.dtype == torch.float64
    assert float(filled[0]) == pytest.approx(1 / 0.01**3, rel=0.05)
    assert float(filled[2]) == pytest.approx(1 / 0.008**3, rel=0.05)
    assert float(filled[1]) == 1.0
    none = calibrate(x, torch.full_like(frag, -1))
    assert none["radius"] == 0.0 and torch.equal(none["filled"], torch.ones(1, dtype=torch.float64))


def test_near_foreign_marks_particles_with_another_fragment_within_one_cell():
    """Particles binned into cells of edge 1 (one per cell on a line, and one unlabelled particle alone far out):
    a particle is marked exactly when a particle of another fragment id (−1 counting as an id) sits in its cell or
    a neighbouring one; empty neighbouring cells count as no id, so a lone fragment, or the lone unlabelled
    particle, marks nothing."""
    x = torch.tensor([[i + 0.5, 0.5, 0.5] for i in [*range(10), 20]], dtype=torch.float64)
    lo = torch.zeros(3, dtype=torch.float64)
    frag = torch.tensor([0, 0, 0, 1, 1, 1, 1, 2, 2, 2, -1])
    got = _Cells(x, frag, lo, 1.0).near_foreign()
    assert torch.equal(got, torch.tensor([0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 0], dtype=torch.bool))
    frag = torch.tensor([0, 0, 0, 0, 0, -1, 0, 0, 0, 0, -1])
    got = _Cells(x, frag, lo, 1.0).near_foreign()
    assert torch.equal(got, torch.tensor([0, 0, 0, 0, 1, 1, 1, 0, 0, 0, 0], dtype=torch.bool))
    one = _Cells(x, torch.full((11,), 3), lo, 1.0).near_foreign()
    assert not bool(one.any())
