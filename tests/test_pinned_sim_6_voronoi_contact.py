"""When the Voronoi shatter's `latch_on_contact` is due (`sim.providers.voronoi.VoronoiProvider.due`): once some
particle lies closer than Δx to a plane collider, measured along the plane's unit normal (signed: a particle
behind the plane is closer still), on any one of the scene's planes. Exactly Δx away is not yet contact.
Unit-level: the provider reads the particles, the grid's Δx and the boundaries from a stand-in simulator; the
distances are powers of two, exact in float32 and float64."""

import types

import torch

from fracture_gs.config import PlaneBoundary, TopologyConfig
from fracture_gs.sim.providers.voronoi import VoronoiProvider

DX = 0.0625
CFG = TopologyConfig(provider="voronoi", cells=3, latch_on_contact=True, split_components=False)
FLOOR = PlaneBoundary(point=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 4.0))  # the normal's length does not matter
WALL = PlaneBoundary(point=(1.0, 0.0, 0.0), normal=(-1.0, 0.0, 0.0))  # x = 1, facing −x


def _due(lowest_z, highest_x=0.5, planes=(FLOOR, WALL)):
    """Whether the provider is due for a 3-particle column whose lowest z and highest x are given."""
    x = torch.tensor([[0.25, 0.5, lowest_z], [0.375, 0.5, 0.5], [highest_x, 0.5, 0.625]], dtype=torch.float32)
    sim = types.SimpleNamespace(
        particles=types.SimpleNamespace(x=x),
        grid=types.SimpleNamespace(dx=DX),
        cfg=types.SimpleNamespace(boundaries=list(planes), max_fragments=64),
        frame=0,
        time=0.0,
    )
    return VoronoiProvider(CFG).due(sim)


def test_contact_is_strictly_closer_than_one_cell_to_any_plane():
    """Lowest particle exactly Δx above the floor (and far from the wall): not due; 2⁻¹⁰ closer: due; on the floor
    and below it (z < 0): due. The wall alone decides the same way along its own normal: its nearest particle exactly
    Δx from x = 1 is not contact, 2⁻¹⁰ closer is, whichever plane is listed first."""
    assert not _due(DX)
    assert _due(DX - 2**-10)
    assert _due(0.0) and _due(-0.125)
    assert not _due(0.5, highest_x=1.0 - DX)
    assert _due(0.5, highest_x=1.0 - DX + 2**-10)
    assert _due(0.5, highest_x=1.0 - DX + 2**-10, planes=(WALL, FLOOR))
    assert not _due(0.5, planes=())
