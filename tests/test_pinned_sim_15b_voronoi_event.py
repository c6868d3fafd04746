"""`sim/providers/voronoi.py`: the impact kernel's default spread and the shatter event as it is saved with the run.

- `voronoi_sites(x, cells, seed, impact_point)` without a radius draws around the impact with σ = 0.1 m (the
  `TopologyConfig.impact_radius` default): the same sites as σ = 0.1 given explicitly, seed for seed, and sites that
  stay within a few σ of the impact.
- The shatter event records `parents = (−1,)` ("the unbroken object", as the plane provider's first event does) and
  children 0 … K − 1; with `split_components`, a cell made of disconnected pieces joins the parents once (after −1,
  however many pieces it gave), its smaller pieces take new ids in order of size and join the children."""

import types

import torch

from fracture_gs.config import TopologyConfig
from fracture_gs.sim.providers.voronoi import VoronoiProvider, voronoi_sites
from fracture_gs.sim.topology import Topology


def _block(n=8, side=1.0, shift=(0.0, 0.0, 0.0)):
    g = torch.linspace(0.0, side, n)
    x = torch.stack(torch.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    return x + torch.tensor(shift)


def _sim(x, dx=0.05, max_fragments=64, frame=3, time=0.125):
    return types.SimpleNamespace(
        particles=types.SimpleNamespace(x=x),
        grid=types.SimpleNamespace(dx=dx),
        cfg=types.SimpleNamespace(max_fragments=max_fragments, boundaries=[]),
        frame=frame,
        time=time,
        device="cpu",
    )


def test_the_default_impact_radius_is_a_tenth_of_a_metre():
    """A 1 m block of 512 particles, impact at a corner, 6 cells: with no radius given the sites are those of
    σ = 0.1 m for every seed (not those of σ = 0.9 or 1.1), and all lie within 0.5 m (5σ) of the corner."""
    x, corner = _block(), (0.0, 0.0, 0.0)
    assert TopologyConfig().impact_radius == 0.1
    wide = 0
    for seed in range(8):
        sites = voronoi_sites(x, 6, seed, corner)
        assert torch.equal(sites, voronoi_sites(x, 6, seed, corner, 0.1)), seed
        assert float(sites.norm(dim=1).max()) < 0.5, seed
        wide += not torch.equal(sites, voronoi_sites(x, 6, seed, corner, 0.9))
    assert wide >= 6  # a wider kernel draws other sites: the comparison above can tell them apart


def test_the_shatter_event_comes_from_the_unbroken_object():
    """Without component splitting: one "voronoi" event at the simulator's time and frame, parents (−1,), children
    0 … K − 1, seeds = the sites, and the snapshot latched at that time and frame."""
    x = _block(6, 0.5)
    p = VoronoiProvider(TopologyConfig(provider="voronoi", cells=5, seed=2, split_components=False))
    topo = p(_sim(x))
    (event,) = topo.events
    assert (event.kind, event.time, event.frame) == ("voronoi", 0.125, 3)
    assert event.parents == (-1,) and event.children == (0, 1, 2, 3, 4)
    assert event.seeds == p.sites.tolist()
    assert (topo.latch_time, topo.latch_frame) == (0.125, 3)


def test_a_cell_split_into_pieces_joins_the_parents_once_after_the_unbroken_object():
    """One Voronoi cell over three disconnected blocks (0.35 m, 0.25 m and 0.25 m, 0.25 m apart; cells of
    Δx = 0.1 m for the connectivity): the cell (fragment 0) splits, the largest block keeps id 0, the two smaller
    ones take ids 1 and 2 in order of size, and the event reads parents (−1, 0) — fragment 0 listed once however
    many pieces it gave — and children (0, 1, 2)."""
    big = _block(8, 0.35)
    mid = _block(6, 0.25, shift=(0.6, 0.0, 0.0))
    small = _block(5, 0.25, shift=(0.0, 0.6, 0.0))
    x = torch.cat([big, mid, small])
    cfg = TopologyConfig(provider="voronoi", cells=1, seed=0, split_components=True, min_fragment_particles=8)
    topo = VoronoiProvider(cfg)(_sim(x, dx=0.1))
    (event,) = topo.events
    assert event.parents == (-1, 0) and event.children == (0, 1, 2)
    want = torch.cat([torch.full((len(b),), i, dtype=torch.int32) for i, b in enumerate((big, mid, small))])
    assert torch.equal(topo.fragment, want)
    assert isinstance(topo, Topology) and topo.n_fragments == 3


def test_the_snapshot_carries_the_configs_pair_radius_and_release_with_or_without_splitting():
    """The Voronoi snapshot's pair radius is `pair_radius`, its released events follow `release` (first → 1,
    all → every event, none → 0) whether or not components are split, its normal is +x (a shatter has no single
    plane) and its point the first site."""
    x = _block(6, 0.5)
    for split in (False, True):
        for release, events in (("first", 1), ("all", 1 << 30), ("none", 0)):
            cfg = TopologyConfig(
                provider="voronoi", cells=4, seed=5, split_components=split, release=release, pair_radius=2.25
            )
            p = VoronoiProvider(cfg)
            topo = p(_sim(x))
            assert topo.pair_radius == 2.25 and topo.release_events == events, (split, release)
            assert topo.normal == (1.0, 0.0, 0.0) and topo.point == tuple(p.sites[0].tolist())
