"""Hand-written bug campaign, round two: fracture providers (`sim.providers.cuts`, `sim.providers.voronoi`).

- A plane cut gives the new id to the particles on the positive side, the plane itself included (d ≥ 0), whichever
  way the normal points; the band is the cut fragment's particles with |d| < band_width.
- A Voronoi shatter latched on contact fires when a particle comes within Δx of a plane collider, measured along
  the plane's unit normal whatever the length the config gives it.
"""

from types import SimpleNamespace

import pytest
import torch

from fracture_gs.config import PlaneBoundary, SimConfig, TopologyConfig
from fracture_gs.sim.providers.cuts import plane_cut
from fracture_gs.sim.providers.voronoi import VoronoiProvider


@pytest.mark.parametrize("sign,expected", [(1.0, [0, 1, 1, 1]), (-1.0, [1, 1, 0, 0])])
def test_a_plane_cut_gives_the_plane_itself_to_the_positive_side(sign, expected):
    """Particles at x = 1/4, 1/2 (on the plane x = 1/2), 5/8, 3/4: normal +x gives the new id 1 to x ≥ 1/2; normal −x
    to x ≤ 1/2. With band_width 3/16 the band is the three particles within 3/16 of the plane (not the far one)."""
    xs = [0.25, 0.5, 0.625, 0.75]
    x = torch.tensor([[a, 0.5, 0.5] for a in xs])
    fragment, band = torch.zeros(4, dtype=torch.int32), torch.zeros(4, dtype=torch.int32)
    f, b, parents, children = plane_cut(x, fragment, band, (0.5, 0.0, 0.0), (sign, 0.0, 0.0), 0.1875, 8)
    assert f.tolist() == expected
    assert b.tolist() == [0, 1, 1, 0]
    assert (parents, children) == ([0], [1])


@pytest.mark.parametrize("length", [1.0, 2.0, 0.5])
def test_a_contact_latch_measures_along_the_unit_normal(length):
    """Floor z = 1/4 with normal (0, 0, length), Δx = 1/16: the lowest particle 3/4 Δx above it fires the latch, one
    5/4 Δx above does not, whatever the normal's length."""
    cfg = TopologyConfig(provider="voronoi", latch_on_contact=True)
    floor = PlaneBoundary(point=(0.0, 0.0, 0.25), normal=(0.0, 0.0, length))
    for height, due in ((0.75, True), (1.25, False)):
        x = torch.tensor([[0.5, 0.5, 0.25 + height / 16], [0.5, 0.5, 0.5]])
        sim = SimpleNamespace(cfg=SimConfig(boundaries=[floor]), particles=SimpleNamespace(x=x),
                              grid=SimpleNamespace(dx=1 / 16))  # fmt: skip
        assert VoronoiProvider(cfg).due(sim) is due, f"{height} Δx above the floor"
